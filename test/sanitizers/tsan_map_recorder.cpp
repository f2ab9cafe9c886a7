// ThreadSanitizer driver for the map recorder's writer thread (built and run by scripts/run_sanitizers.sh
// with a rosmaster of its own; ROS_MASTER_URI must name it).
//
// The map_recorder nodelet hands keyframes from its callbacks (images, ~start, ~pause, ~finish) to a
// writer thread that flushes the map file (src/nodelets/map_recorder_nodelet.cpp). This program loads the
// real nodelet, ThreadSanitizer-built, into an in-process nodelet::Loader (the manager's own worker
// threads run its callback queue), streams frames at it with a short flush period so that flushes
// overlap with callbacks, pauses and resumes, finishes, and checks the map it wrote.
#include <stdlib.h>
#include <unistd.h>

#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>

#include "along_route_localization/preprocessing.h"
#include "glue/map_io.h"

namespace arl = along_route_localization;

namespace
{

const char kRecorder[] = "/tsan/map_recorder";

sensor_msgs::ImageConstPtr frame(int index)
{
  cv::Mat image(32, 64, CV_8UC1);
  cv::RNG rng(7000 + index);
  rng.fill(image, cv::RNG::UNIFORM, 0, 256);
  return arl::keyframeMessage(image, 1000000000LL * (index + 1));
}

/// Waits (bounded) until `publisher` has a subscriber.
bool waitForSubscriber(const ros::Publisher& publisher, double timeout_s)
{
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(timeout_s);
  while (publisher.getNumSubscribers() == 0)
  {
    if (ros::WallTime::now() > deadline)
      return false;
    ros::WallDuration(0.01).sleep();
  }
  return true;
}

std::string callTrigger(const std::string& service, bool* success)
{
  std_srvs::Trigger trigger;
  if (!ros::service::waitForService(service, ros::Duration(10.0)) || !ros::service::call(service, trigger))
  {
    *success = false;
    return "service " + service + " could not be called";
  }
  *success = trigger.response.success;
  return trigger.response.message;
}

TEST(MapRecorderThreads, WriterThreadRecordsWhatTheCallbacksQueued)
{
  char pattern[] = "/tmp/along_route_tsan_recorder_XXXXXX";
  ASSERT_NE(mkdtemp(pattern), nullptr);
  const std::string dir = pattern;
  const std::string map_path = dir + "/map.bag";

  ros::NodeHandle nh;
  ros::param::set(std::string(kRecorder) + "/map", map_path);
  ros::param::set(std::string(kRecorder) + "/flush_period", 0.01);  // flushes overlap with the callbacks
  ros::param::set(std::string(kRecorder) + "/queue_size", 1000);    // no frame dropped by the subscriber
  ros::Publisher params_pub = nh.advertise<std_msgs::String>("/tsan/preprocessing_params", 1, true);
  ros::Publisher image_pub = nh.advertise<sensor_msgs::Image>("/tsan/image_preprocessed", 1000);
  std_msgs::String params;
  params.data = arl::PreprocessingParams().serialize();
  params_pub.publish(params);

  {
    nodelet::Loader manager(false);
    ASSERT_TRUE(manager.load(kRecorder, "along_route_localization/map_recorder", nodelet::M_string(),
                             nodelet::V_string()));
    // Subscribed in onInit: the latched parameters are queued on connection, before any image below
    // (one callback queue, first in first out).
    ASSERT_TRUE(waitForSubscriber(params_pub, 10.0));
    ASSERT_TRUE(waitForSubscriber(image_pub, 10.0));

    std::vector<int64_t> expected_stamps;
    int index = 0;
    const auto publish = [&](int count, bool recorded) {
      for (int i = 0; i < count; ++i, ++index)
      {
        const sensor_msgs::ImageConstPtr image = frame(index);
        if (recorded)
          expected_stamps.push_back(static_cast<int64_t>(image->header.stamp.toNSec()));
        image_pub.publish(image);
        ros::WallDuration(0.001).sleep();
      }
    };
    bool success = false;
    publish(60, true);
    // Service requests are queued after the images published before the call, and the call returns
    // after the callback ran: frames published while paused are not recorded.
    std::string message = callTrigger(std::string(kRecorder) + "/pause", &success);
    EXPECT_TRUE(success) << message;
    publish(20, false);
    message = callTrigger(std::string(kRecorder) + "/start", &success);
    EXPECT_TRUE(success) << message;
    publish(60, true);
    message = callTrigger(std::string(kRecorder) + "/finish", &success);
    EXPECT_TRUE(success) << message;
    EXPECT_NE(message.find("holds 120 keyframes"), std::string::npos) << message;
    ASSERT_TRUE(manager.unload(kRecorder));  // joins the writer thread

    const arl::RouteMap map = arl::readMap(map_path);
    ASSERT_EQ(map.size(), expected_stamps.size());
    for (size_t k = 0; k < map.size(); ++k)
      EXPECT_EQ(expected_stamps[k], map.stampNs(k)) << "keyframe " << k;
  }
  const std::string command = "rm -rf '" + dir + "'";
  EXPECT_EQ(std::system(command.c_str()), 0);
}

}  // namespace

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "tsan_map_recorder", ros::init_options::NoSigintHandler);
  const ros::WallTime deadline = ros::WallTime::now() + ros::WallDuration(20.0);
  while (!ros::master::check())
  {
    if (ros::WallTime::now() > deadline)
    {
      std::fprintf(stderr, "tsan_map_recorder: no ROS master at %s\n", ros::master::getURI().c_str());
      return 2;
    }
    ros::WallDuration(0.1).sleep();
  }
  ros::AsyncSpinner spinner(1);  // the global queue: service clients, parameter updates
  spinner.start();
  const int result = RUN_ALL_TESTS();
  spinner.stop();
  ros::shutdown();
  return result;
}
