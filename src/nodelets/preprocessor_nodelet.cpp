// Step 1 of the method as a nodelet: camera image in, small normalized mono8 image out, computed
// straight into the outgoing message.
//
// Subscribes: image (sensor_msgs/Image via image_transport; any encoding the core accepts)
// Publishes:  image_preprocessed (mono8, header copied from the input)
//             <namespace of image_preprocessed>/preprocessing_params (std_msgs/String, latched):
//             the parameters that make the images, published right before the first image made
//             with a new value (see map_io.h)
//             /diagnostics (images in, published, dropped and why, clipped or enlarged)
// Parameters: cfg/Preprocessor.cfg (dynamic); ~queue_size (static, default 5)
#include <algorithm>
#include <cstdio>
#include <memory>
#include <mutex>
#include <set>
#include <string>

#include <boost/thread/recursive_mutex.hpp>
#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <nodelet/nodelet.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>

#include "along_route_localization/PreprocessorConfig.h"
#include "along_route_localization/parameters.h"
#include "along_route_localization/preprocessing.h"
#include "glue/diagnostics.h"
#include "glue/image_message.h"
#include "glue/image_subscription.h"
#include "glue/map_io.h"
#include "glue/private_parameters.h"
#include "glue/reconfigure.h"

namespace along_route_localization
{

class PreprocessorNodelet : public nodelet::Nodelet
{
private:
  void onInit() override;
  void connectCb();
  void imageCb(const sensor_msgs::ImageConstPtr& msg);
  void configCb(PreprocessorConfig& config, uint32_t level);
  /// Drops the image: counted for the diagnostics, and said at most once per 5 s for each kind of
  /// problem (an ImageProblem, or kNone for a failure while preprocessing) so a second kind is said at once.
  void dropImage(ImageProblem kind, const std::string& sentence);
  void announce(const PreprocessingParams& params);
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  std::shared_ptr<image_transport::ImageTransport> it_;
  int queue_size_ = 5;
  std::string image_topic_;  // resolved input topic

  // Lazy subscription: subscribed only while someone listens to image_preprocessed.
  std::mutex connect_mutex_;
  image_transport::Subscriber sub_;
  std::string transport_error_;  // why images cannot be subscribed to (a missing transport plugin), or ""
  image_transport::Publisher pub_;
  ros::Publisher params_pub_;
  std::shared_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostics_timer_;

  // Held by the reconfigure server around configCb, and by onInit's first announcement.
  boost::recursive_mutex config_mutex_;
  std::shared_ptr<dynamic_reconfigure::Server<PreprocessorConfig>> reconfigure_server_;
  PreprocessorConfig last_valid_config_;

  // Used only from the nodelet's single-threaded callback queue (imageCb, configCb, which sets its
  // parameters) after onInit.
  Preprocessor preprocessor_;
  // The diagnostics timer runs on the same queue, so these need no lock either.
  bool in_place_warned_ = false;
  DroppedFrames dropped_;
  uint64_t published_ = 0, clipped_ = 0, enlarged_ = 0;  // images in: published_ + dropped_.count()
  std::string last_warning_;         // what was wrong with the last image used clipped or enlarged
  std::set<std::string> enlarged_said_;  // the warnings about enlarged images logged so far
};

void PreprocessorNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& private_nh = getPrivateNodeHandle();
  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  image_topic_ = nh.resolveName("image");
  // A transport's own topic given as the image (image:=/camera/image_raw/compressed): subscribed to as raw,
  // every message is dropped by roscpp for its type, and only the camera's side said so.
  const size_t slash = image_topic_.find_last_of('/');
  const std::string transport = image_topic_.substr(slash + 1);
  if (slash != std::string::npos && slash > 0 &&
      (transport == "compressed" || transport == "compressedDepth" || transport == "theora"))
    NODELET_ERROR("The image topic %s is the '%s' transport of %s, which this nodelet cannot read as an image: "
                  "give the base topic (image:=%s) and set ~image_transport to %s",
                  image_topic_.c_str(), transport.c_str(), image_topic_.substr(0, slash).c_str(),
                  image_topic_.substr(0, slash).c_str(), transport.c_str());
  transport_error_ = transportProblem(private_nh);  // said now: the subscription comes with a subscriber
  if (!transport_error_.empty())
    NODELET_ERROR("Images on %s: %s", image_topic_.c_str(), transport_error_.c_str());
  const std::set<std::string>& own = nodeletSettingNames(ParameterGroup::kPreprocessor);
  std::set<std::string> read = configParameterNames<PreprocessorConfig>();
  read.insert(own.begin(), own.end());
  for (const std::string& name : unreadParameters(private_nh, read))
    NODELET_WARN("%s", unreadSentence(name, "preprocessor", read).c_str());
  std::string problem;
  queue_size_ = readIntParameter(private_nh, "queue_size", queue_size_, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (queue_size_ < 1)
  {
    NODELET_ERROR("~queue_size must be at least 1 (%d); using 1", queue_size_);
    queue_size_ = 1;
  }

  last_valid_config_ = PreprocessorConfig::__getDefault__();
  for (const std::string& sentence : mistypedParameters<PreprocessorConfig>(private_nh))
    NODELET_WARN("%s", sentence.c_str());
  // The announcement's publisher before the reconfigure server: a set_parameters call may come while
  // onInit goes on, and its configCb announces (under config_mutex_, as the server holds it).
  const std::string params_topic = preprocessingParamsTopic(nh.resolveName("image_preprocessed"));
  params_pub_ = nh.advertise<std_msgs::String>(params_topic, 1, true);
  reconfigure_server_ = std::make_shared<dynamic_reconfigure::Server<PreprocessorConfig>>(config_mutex_, private_nh);
  reconfigure_server_->setCallback([this](PreprocessorConfig& config, uint32_t level) { configCb(config, level); });

  // Announce the starting parameters before any image, so downstream nodelets can check maps now; under
  // config_mutex_, so that a configCb running meanwhile comes before or after, not in between.
  PreprocessingParams initial;
  {
    std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
    initial = preprocessor_.params();  // configCb's, from the server's first call
    announce(initial);
  }

  std::lock_guard<std::mutex> lock(connect_mutex_);
  const image_transport::SubscriberStatusCallback connect_cb =
      [this](const image_transport::SingleSubscriberPublisher&) { connectCb(); };
  pub_ = it_->advertise("image_preprocessed", 1, connect_cb, connect_cb);
  updater_ = std::make_shared<diagnostic_updater::Updater>(nh, private_nh, getName());
  updater_->setHardwareID("none");
  updater_->add("preprocessing", this, &PreprocessorNodelet::diagnose);
  diagnostics_timer_ = startDiagnosticsTimer(nh, updater_);
  NODELET_INFO("Preprocessing %s -> %s (%s); parameters on %s", image_topic_.c_str(),
               nh.resolveName("image_preprocessed").c_str(), initial.serialize().c_str(), params_topic.c_str());
}

void PreprocessorNodelet::connectCb()
{
  std::lock_guard<std::mutex> lock(connect_mutex_);
  if (pub_.getNumSubscribers() == 0)
  {
    sub_.shutdown();
  }
  else if (!sub_ && transport_error_.empty())  // a missing transport plugin: only a new load tries again
  {
    std::string error;
    sub_ = subscribeTransported(*it_, "image", static_cast<uint32_t>(queue_size_), &PreprocessorNodelet::imageCb,
                                this, getPrivateNodeHandle(), &error);
    if (!error.empty())
      NODELET_ERROR("Images on %s: %s", image_topic_.c_str(), error.c_str());
    transport_error_ = error;
  }
}

void PreprocessorNodelet::configCb(PreprocessorConfig& config, uint32_t /*level*/)
{
  // Corrections, so the panel shows the values in use: each value into its working range, then the
  // combinations.
  std::vector<std::string> corrections = correctToTable(config, last_valid_config_);
  std::string invalid;
  PreprocessingParams params = toParams(config, &invalid);
  if (invalid.empty())
  {
    for (std::string& sentence : params.correctCombinations())
      corrections.push_back(std::move(sentence));
    config.filter_window = params.filter_window;
    config.patch_size = params.patch_size;
    invalid = params.validate();
  }
  const ConfigReview review = reviewConfig(config, last_valid_config_, std::move(corrections), invalid);
  logConfigReview(review, getName(), "preprocessing parameters");
  if (!review.rejected.empty())
    return;
  // Applied and announced now, not at the next image: downstream nodelets check maps against the
  // announcement, and while no image comes (a localizer without a map does not subscribe, so none is
  // asked for) a map made with the new parameters was refused. The reconfigure service runs on the same
  // single-threaded queue as imageCb, so the announcement still comes before the first image made with them.
  if (params != preprocessor_.params())
  {
    preprocessor_.setParams(params);
    announce(params);
    NODELET_INFO("Preprocessing parameters now %s", params.serialize().c_str());
  }
}

void PreprocessorNodelet::announce(const PreprocessingParams& params)
{
  std_msgs::StringPtr msg = boost::make_shared<std_msgs::String>();
  msg->data = params.serialize();
  params_pub_.publish(msg);
}

void PreprocessorNodelet::dropImage(ImageProblem kind, const std::string& sentence)
{
  if (dropped_.drop(static_cast<int>(kind), sentence))
    NODELET_ERROR("Dropping %s", sentence.c_str());
}

void PreprocessorNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  const uint64_t images_in = published_ + dropped_.count();
  std::string transport_error;
  {
    std::lock_guard<std::mutex> lock(connect_mutex_);
    transport_error = transport_error_;
  }
  if (!transport_error.empty())
  {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                 "not subscribed to " + image_topic_ + ": " + transport_error);
  }
  else if (images_in == 0)
  {
    if (pub_.getNumSubscribers() == 0)
      stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "idle: nothing subscribes to " + pub_.getTopic());
    else
      stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for images on " + image_topic_);
  }
  else if (dropped_.newestDropped())
  {
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "dropping " + dropped_.lastReason());
  }
  else if (!last_warning_.empty())
  {
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, last_warning_);
  }
  else
  {
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, "preprocessing");
  }
  stat.add("images in", images_in);
  stat.add("images published", published_);
  dropped_.addTo(stat, "image");
  stat.add("32FC1 images clipped to [0, 1]", clipped_);
  stat.add("images smaller than the output (enlarged)", enlarged_);
  stat.add("parameters", preprocessor_.params().serialize());
}

void PreprocessorNodelet::imageCb(const sensor_msgs::ImageConstPtr& msg)
{
  const PreprocessingParams& params = preprocessor_.params();  // set by configCb, on this queue
  PixelFormat format;
  std::string problem;
  const ImageProblem kind = imageMessageProblem(*msg, &format, &problem);
  if (kind != ImageProblem::kNone)
  {
    dropImage(kind, problem);
    return;
  }

  const sensor_msgs::ImagePtr out = boost::make_shared<sensor_msgs::Image>();
  out->header = msg->header;
  out->encoding = sensor_msgs::image_encodings::MONO8;
  out->width = static_cast<uint32_t>(params.output_width);
  out->height = static_cast<uint32_t>(params.output_height);
  out->step = out->width;
  out->is_bigendian = 0;
  out->data.resize(static_cast<size_t>(out->step) * out->height);
  cv::Mat output(params.output_height, params.output_width, CV_8UC1, &out->data[0], out->step);
  // For the messages only: formatted when one is needed, not for every image.
  const auto image = [&msg]() {
    char text[160];
    std::snprintf(text, sizeof(text), "a %ux%u '%s' image", msg->width, msg->height, msg->encoding.c_str());
    return std::string(text);
  };
  try
  {
    const cv_bridge::CvImageConstPtr input = cv_bridge::toCvShare(msg);
    std::string warning;
    if (format == PixelFormat::kMono32F && floatOutsideUnitRange(input->image, &warning))
    {
      ++clipped_;
      last_warning_ = image() + ": " + warning + " (scale the images to [0, 1])";
      NODELET_WARN_THROTTLE(10.0, "Using %s", last_warning_.c_str());
    }
    else if (inputSmallerThanOutput(input->image.cols, input->image.rows, params, &warning))
    {
      ++enlarged_;
      last_warning_ = image() + " " + warning;
      // Said once for each input and output size (a camera mode), and kept in the diagnostics.
      if (enlarged_said_.size() < 64 && enlarged_said_.insert(last_warning_).second)
        NODELET_WARN("Using %s", last_warning_.c_str());
    }
    else
    {
      last_warning_.clear();
    }
    preprocessor_.process(input->image, format, output);
  }
  catch (const std::exception& e)  // PreprocessingError, cv_bridge::Exception, cv::Exception
  {
    dropImage(ImageProblem::kNone, image() + ": " + e.what());
    return;
  }
  if (output.data != &out->data[0])
  {
    // The core reallocated instead of writing in place; keep the output right, say so once.
    if (!in_place_warned_)
      NODELET_WARN("Preprocessor::process did not write into the message buffer; copying");
    in_place_warned_ = true;
    cv::Mat wrapped(params.output_height, params.output_width, CV_8UC1, &out->data[0], out->step);
    output.copyTo(wrapped);
  }
  pub_.publish(out);
  dropped_.used();
  ++published_;
}

}  // namespace along_route_localization

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(along_route_localization::PreprocessorNodelet, nodelet::Nodelet)
