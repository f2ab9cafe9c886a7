// The preprocessor -> localizer hand-over inside one nodelet manager copies nothing: the localizer runs
// the core on the very buffer of the message the preprocessor published.
//
// This process is the manager (nodelet::Loader) and also subscribes to image_preprocessed itself; roscpp
// hands every subscriber in the process the same shared message. The localizer, with the test hook
// ~report_input_buffer, reports on ~input_buffer the address of the pixels the core read and the stamp
// of that frame; it must be the address of that message's data. Users never see that address: the hook
// is off by default, and /diagnostics does not show it.
#include <chrono>
#include <cstdio>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include <diagnostic_msgs/DiagnosticArray.h>
#include <gtest/gtest.h>
#include <nodelet/loader.h>
#include <ros/ros.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>

#include "along_route_localization/Localization.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"
#include "glue/map_io.h"

namespace arl = along_route_localization;

namespace
{

sensor_msgs::ImagePtr randomFrame(std::mt19937& rng, uint32_t seq)
{
  auto msg = boost::make_shared<sensor_msgs::Image>();
  msg->header.seq = seq;
  msg->header.stamp = ros::Time(1000 + seq / 20, (seq % 20) * 50000000);
  msg->header.frame_id = "camera";
  msg->encoding = sensor_msgs::image_encodings::BGR8;
  msg->width = 128;
  msg->height = 64;
  msg->step = msg->width * 3;
  msg->data.resize(msg->step * msg->height);
  std::uniform_int_distribution<int> byte(0, 255);
  for (auto& b : msg->data)
    b = static_cast<uint8_t>(byte(rng));
  return msg;
}

std::string address(const void* pointer)
{
  char text[32];
  std::snprintf(text, sizeof(text), "%p", pointer);
  return text;
}

}  // namespace

TEST(ZeroCopy, LocalizerReadsThePreprocessorsMessageBuffer)
{
  ros::NodeHandle nh;
  std::mt19937 rng(7);

  // A map of 30 keyframes preprocessed by the core with the default parameters (the preprocessor's).
  std::vector<sensor_msgs::ImagePtr> frames;
  for (uint32_t i = 0; i < 30; ++i)
    frames.push_back(randomFrame(rng, i));
  arl::Preprocessor preprocessor;
  arl::RouteMap map(preprocessor.params());
  for (const auto& frame : frames)
  {
    const cv::Mat input(frame->height, frame->width, CV_8UC3, frame->data.data(), frame->step);
    cv::Mat out;
    preprocessor.process(input, arl::PixelFormat::kBgr8, out);
    map.addKeyframe(out, static_cast<int64_t>(frame->header.stamp.toNSec()));
  }
  const std::string map_path = "/tmp/along_route_zero_copy_" + std::to_string(::getpid()) + ".bag";
  arl::writeMap(map_path, map);
  ros::param::set("/zc/localizer/map", map_path);
  ros::param::set("/zc/localizer/report_input_buffer", true);

  std::mutex mutex;
  std::map<ros::Time, sensor_msgs::ImageConstPtr> preprocessed;  // kept alive: addresses stay unique
  std::map<ros::Time, std::string> core_input;                    // stamp -> address the core read
  size_t localizations = 0;
  ros::Subscriber image_sub = nh.subscribe<sensor_msgs::Image>(
      "/zc/image_preprocessed", 100, [&](const sensor_msgs::ImageConstPtr& msg) {
        std::lock_guard<std::mutex> lock(mutex);
        preprocessed[msg->header.stamp] = msg;
      });
  ros::Subscriber localization_sub = nh.subscribe<along_route_localization::Localization>(
      "/zc/localization", 100, [&](const along_route_localization::LocalizationConstPtr&) {
        std::lock_guard<std::mutex> lock(mutex);
        ++localizations;
      });
  ros::Subscriber input_buffer_sub = nh.subscribe<std_msgs::String>(
      "/zc/localizer/input_buffer", 100, [&](const std_msgs::StringConstPtr& msg) {
        unsigned sec = 0, nsec = 0;
        char pointer[32] = { 0 };
        if (std::sscanf(msg->data.c_str(), "%31s @ %u.%u", pointer, &sec, &nsec) == 3 && sec > 0)
        {
          std::lock_guard<std::mutex> lock(mutex);
          core_input[ros::Time(sec, nsec)] = pointer;
        }
      });
  // What users read: no value of the localizer's diagnostics is a memory address.
  std::vector<std::string> addresses_in_diagnostics;
  size_t localizer_statuses = 0;
  ros::Subscriber diagnostics_sub = nh.subscribe<diagnostic_msgs::DiagnosticArray>(
      "/diagnostics", 100, [&](const diagnostic_msgs::DiagnosticArrayConstPtr& msg) {
        std::lock_guard<std::mutex> lock(mutex);
        for (const auto& status : msg->status)
        {
          if (status.name.find("localizer") == std::string::npos)
            continue;
          ++localizer_statuses;
          for (const auto& kv : status.values)
            if (kv.value.find("0x") != std::string::npos)
              addresses_in_diagnostics.push_back(kv.key + ": " + kv.value);
        }
      });
  ros::AsyncSpinner spinner(2);
  spinner.start();

  nodelet::Loader manager(false);
  const nodelet::M_string no_remapping;
  const nodelet::V_string no_args;
  ASSERT_TRUE(manager.load("/zc/preprocessor", "along_route_localization/preprocessor", no_remapping, no_args));
  ASSERT_TRUE(manager.load("/zc/localizer", "along_route_localization/localizer", no_remapping, no_args));

  ros::Publisher camera = nh.advertise<sensor_msgs::Image>("/zc/image", 10);
  const auto connected_by = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (camera.getNumSubscribers() == 0 && std::chrono::steady_clock::now() < connected_by)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_GT(camera.getNumSubscribers(), 0u) << "the preprocessor never subscribed to /zc/image";

  // Frames keep coming (20 Hz) until the localizer reports a frame we also received, and its diagnostics
  // have been seen.
  bool matched = false;
  std::string core_address, message_address;
  uint32_t seq = 100;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!(matched && localizer_statuses > 0) && std::chrono::steady_clock::now() < deadline)
  {
    camera.publish(randomFrame(rng, seq++));
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    std::lock_guard<std::mutex> lock(mutex);
    for (const auto& reported : core_input)
    {
      const auto it = preprocessed.find(reported.first);
      if (it != preprocessed.end())
      {
        matched = true;
        core_address = reported.second;
        message_address = address(it->second->data.data());
        break;
      }
    }
  }
  spinner.stop();
  manager.clear();
  std::remove(map_path.c_str());
  ASSERT_TRUE(matched) << "no report of a frame received here within 60 s (" << localizations
                       << " localizations, " << preprocessed.size() << " preprocessed frames)";
  EXPECT_GT(localizations, 0u);
  EXPECT_EQ(message_address, core_address);
  std::lock_guard<std::mutex> lock(mutex);
  ASSERT_GT(localizer_statuses, 0u) << "no diagnostics from the localizer within 60 s";
  EXPECT_TRUE(addresses_in_diagnostics.empty()) << addresses_in_diagnostics.front();
}

int main(int argc, char** argv)
{
  testing::InitGoogleTest(&argc, argv);
  ros::init(argc, argv, "test_zero_copy");
  return RUN_ALL_TESTS();
}
