// Teach: picks keyframes from the preprocessed images and writes the route map (map_io.h) as it goes.
//
// Subscribes: image_preprocessed (mono8), from the first time it records (at load with ~autostart, else
//             at a ~start that succeeds; not while the map cannot be written): a play that waits for
//             subscribers waits for a recorder that can record
//             <namespace of image_preprocessed>/preprocessing_params (latched, from the preprocessor):
//             stored in the map, so the map records exactly what made its keyframes
//             odom (nav_msgs/Odometry, optional: only the min_distance policy reads it)
//             motion (optional; geometry_msgs/Twist, or nav_msgs/Odometry with ~motion_type odometry; none:
//             not read): the taught motion stored with each keyframe on the map's topic "motion" (KeyframeMotion.msg):
//             the mean velocity of the messages since the previous keyframe (the latest when none came),
//             the distance since the previous keyframe (twist: |linear.x| integrated over receipt times,
//             each held at most 1 s; odometry: the path of the poses), both counted only while recording
//             (not before ~start, not during ~pause). Keyframes taken before the first motion message
//             heard while recording get none.
// Publishes:  /diagnostics (state, keyframes taken and written, the writer's backlog, frames not
//             recorded and why the last one was not)
// Services:   ~start (refused, with the reason, when the map could not be written: a `.active` left by an
//             interrupted recording, a folder that is missing or takes no file), ~pause, ~finish
//             (std_srvs/Trigger; says how many frames seen while recording were not recorded, and why,
//             and how many keyframes taken could not be written)
// Frames stamped before the last keyframe are not recorded (time went back: a looping bag would record
// the route again after its end).
// Parameters: ~map (absolute path of the map file), ~autostart (true), ~flush_period (1.0 s),
//             ~motion_type (twist | odometry | none; twist),
//             ~max_queue (1000 keyframes waiting for the writer), ~queue_size (100);
//             keyframe policy in cfg/MapRecorder.cfg (dynamic)
//
// Disk I/O happens only in the writer thread. It flushes at least every flush_period, and each flush
// leaves a complete map under the final name, so a killed teach keeps everything up to the last
// flush. ~finish, unloading the nodelet and SIGINT to the manager all close the map.
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <deque>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>

#include <boost/thread/recursive_mutex.hpp>
#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <image_transport/image_transport.h>
#include <geometry_msgs/Twist.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>

#include "along_route_localization/MapRecorderConfig.h"
#include "along_route_localization/parameters.h"
#include "along_route_localization/preprocessing.h"
#include "glue/diagnostics.h"
#include "glue/image_subscription.h"
#include "glue/map_io.h"
#include "glue/private_parameters.h"
#include "glue/reconfigure.h"

namespace along_route_localization
{

class MapRecorderNodelet : public nodelet::Nodelet
{
public:
  ~MapRecorderNodelet() override;

private:
  enum class State
  {
    kIdle,
    kRecording,
    kPaused,
    kFinished
  };

  void onInit() override;
  void imageCb(const sensor_msgs::ImageConstPtr& msg);
  void paramsCb(const std_msgs::StringConstPtr& msg);
  void odomCb(const nav_msgs::OdometryConstPtr& msg);
  void motionTwistCb(const geometry_msgs::TwistConstPtr& msg);
  void motionOdomCb(const nav_msgs::OdometryConstPtr& msg);
  /// One velocity: the latest always, into the keyframe's sum only while `recording`.
  void addMotion(double linear_mps, double angular_rps, bool recording);
  bool recording();
  /// The motion since the previous keyframe (null before the first motion message); starts the next sum.
  KeyframeMotionPtr takeMotion(const std_msgs::Header& keyframe_header, bool first_keyframe);
  void configCb(MapRecorderConfig& config, uint32_t level);
  bool startCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool pauseCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool finishCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool isKeyframe(const sensor_msgs::ImageConstPtr& msg, const KeyframePolicy& policy);
  /// Kinds of reason not to record a frame that arrived while recording (DroppedFrames logs each apart).
  enum Refusal
  {
    kWriterFailed,
    kNoParameters,  // the only one that is expected (at start-up), so a warning
    kParametersChanged,
    kWrongSize,
    kWriterBehind,
    kTimeWentBack
  };
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);
  /// "; not recorded: 244 of the 600 frames seen while recording (...)", or empty when none was lost.
  std::string lossSentence() const;
  void writerLoop();

  // Static parameters, read in onInit.
  std::string map_path_;
  double flush_period_s_ = 1.0;
  size_t max_queue_ = 1000;

  /// Subscribes to the preprocessed images, once: when the recorder first records (at load with ~autostart,
  /// else at a ~start that succeeds). A recorder that cannot or may not record yet does not pull frames, so
  /// `rosbag play --wait-for-subscribers` waits for it instead of playing the teach into the void.
  void subscribeImages();

  std::shared_ptr<image_transport::ImageTransport> it_;
  std::mutex image_sub_mutex_;  // onInit, startCb, diagnose
  image_transport::Subscriber image_sub_;
  std::string transport_error_;  // why images cannot be subscribed to (a missing transport plugin), or ""; guarded
                                 // by image_sub_mutex_
  std::string image_topic_;  // resolved in onInit
  uint32_t image_queue_size_ = 100;
  ros::Subscriber params_sub_, odom_sub_, motion_sub_;
  std::string motion_topic_;
  MotionType motion_type_ = MotionType::kNone;  // set in onInit
  bool motion_type_warned_ = false;             // the motion topic's type problem was logged (diagnose)
  ros::ServiceServer start_srv_, pause_srv_, finish_srv_;
  std::shared_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostics_timer_;

  // Keyframe policy: written by configCb, copied by imageCb; guarded by config_mutex_.
  boost::recursive_mutex config_mutex_;
  std::shared_ptr<dynamic_reconfigure::Server<MapRecorderConfig>> reconfigure_server_;
  KeyframePolicy policy_;
  MapRecorderConfig last_valid_config_ = MapRecorderConfig::__getDefault__();

  // Used only from the nodelet's single-threaded callback queue (image, params, odom, services).
  std::shared_ptr<const PreprocessingParams> announced_params_;
  sensor_msgs::ImageConstPtr last_keyframe_;
  int frames_since_keyframe_ = 0;
  double distance_since_keyframe_m_ = 0.0;
  bool have_odom_ = false;
  double last_x_ = 0.0, last_y_ = 0.0, last_z_ = 0.0;
  uint64_t frames_seen_ = 0;  // while recording
  DroppedFrames refused_;     // frames seen while recording and not recorded
  // The taught motion since the previous keyframe (same queue). Only what the robot did while recording
  // counts: driving before ~start or during ~pause (backing into the start pose) is not taught motion.
  uint64_t motion_messages_ = 0;
  double motion_sum_linear_ = 0.0, motion_sum_angular_ = 0.0;
  int motion_count_ = 0;
  double latest_linear_ = 0.0, latest_angular_ = 0.0;
  bool latest_while_recording_ = false;  // the latest motion message came while recording
  ros::Time latest_motion_time_;
  double motion_distance_m_ = 0.0;
  bool have_motion_pose_ = false;
  double motion_x_ = 0.0, motion_y_ = 0.0, motion_z_ = 0.0;
  uint64_t keyframes_with_motion_ = 0;

  // Shared between the callbacks and the writer thread; guarded by queue_mutex_.
  std::mutex queue_mutex_;
  std::condition_variable writer_cv_;    // wakes the writer: keyframes, finish, stop
  std::condition_variable finished_cv_;  // wakes ~finish: the writer closed the map
  State state_ = State::kIdle;
  struct QueuedKeyframe
  {
    sensor_msgs::ImageConstPtr image;
    KeyframeMotionConstPtr motion;  // null when no motion was recorded
  };
  std::deque<QueuedKeyframe> queue_;
  std::shared_ptr<const PreprocessingParams> recording_params_;  // of the map being written
  size_t keyframes_queued_ = 0;
  size_t keyframes_written_ = 0;
  bool finish_requested_ = false;
  bool finish_done_ = false;
  bool stop_writer_ = false;
  std::string writer_error_;
  std::string finish_message_;
  std::string replaced_path_;  // where the map that was at map_path_ before is kept

  std::thread writer_thread_;
};

void MapRecorderNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& private_nh = getPrivateNodeHandle();

  const std::set<std::string>& own = nodeletSettingNames(ParameterGroup::kMapRecorder);
  std::set<std::string> read = configParameterNames<MapRecorderConfig>();
  read.insert(own.begin(), own.end());
  for (const std::string& name : unreadParameters(private_nh, read))
    NODELET_WARN("%s", unreadSentence(name, "map recorder", read).c_str());
  std::string problem;
  map_path_ = readStringParameter(private_nh, "map", std::string(), &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  bool autostart = readBoolParameter(private_nh, "autostart", true, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  flush_period_s_ = readDoubleParameter(private_nh, "flush_period", flush_period_s_, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (!(flush_period_s_ > 0.0 && flush_period_s_ <= 3600.0))
  {
    NODELET_ERROR("~flush_period must be > 0 and <= 3600 s (%g); using 1.0", flush_period_s_);
    flush_period_s_ = 1.0;
  }
  int max_queue = readIntParameter(private_nh, "max_queue", static_cast<int>(max_queue_), &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (max_queue < 1)
  {
    NODELET_ERROR("~max_queue must be at least 1 (%d); using %zu", max_queue, max_queue_);
    max_queue = static_cast<int>(max_queue_);
  }
  max_queue_ = static_cast<size_t>(max_queue);
  int queue_size = readIntParameter(private_nh, "queue_size", 100, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (queue_size < 1)
  {
    NODELET_ERROR("~queue_size must be at least 1 (%d); using 100", queue_size);
    queue_size = 100;
  }

  for (const std::string& sentence : mistypedParameters<MapRecorderConfig>(private_nh))
    NODELET_WARN("%s", sentence.c_str());
  reconfigure_server_ = std::make_shared<dynamic_reconfigure::Server<MapRecorderConfig>>(config_mutex_, private_nh);
  reconfigure_server_->setCallback([this](MapRecorderConfig& config, uint32_t level) { configCb(config, level); });
  updater_ = std::make_shared<diagnostic_updater::Updater>(nh, private_nh, getName());
  updater_->setHardwareID("none");
  updater_->add("recording", this, &MapRecorderNodelet::diagnose);
  // The diagnostics timer starts last: diagnose reads the subscribers, and callbacks may run while onInit
  // goes on.

  if (map_path_.empty())
  {
    NODELET_ERROR("No ~map parameter: set it to the path of the map file to record; nothing will be recorded");
    diagnostics_timer_ = startDiagnosticsTimer(nh, updater_);
    return;
  }
  try
  {
    requireAbsoluteMapPath(map_path_);
    checkMapTarget(map_path_);
  }
  catch (const MapError& e)
  {
    // Said now rather than at the first keyframe; the services still answer, with this error. Not recording
    // (whatever ~autostart says) until a ~start finds the target fixed.
    NODELET_ERROR("Nothing will be recorded until ~start succeeds: %s", e.what());
    writer_error_ = e.what();
    autostart = false;
  }
  {
    std::lock_guard<std::mutex> lock(image_sub_mutex_);
    transport_error_ = transportProblem(private_nh);
    if (!transport_error_.empty())
    {
      NODELET_ERROR("Nothing will be recorded: images on %s: %s", nh.resolveName("image_preprocessed").c_str(),
                    transport_error_.c_str());
      autostart = false;
    }
  }
  struct stat existing;
  if (writer_error_.empty() && ::stat(map_path_.c_str(), &existing) == 0)
    NODELET_WARN("Map %s exists; when the first keyframe is written it is renamed to %s, not overwritten",
                 map_path_.c_str(), replacedMapPath(map_path_, existing.st_mtime).c_str());
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    state_ = autostart ? State::kRecording : State::kIdle;
  }
  writer_thread_ = std::thread(&MapRecorderNodelet::writerLoop, this);

  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  image_topic_ = nh.resolveName("image_preprocessed");
  image_queue_size_ = static_cast<uint32_t>(std::max(1, queue_size));
  start_srv_ = private_nh.advertiseService("start", &MapRecorderNodelet::startCb, this);
  pause_srv_ = private_nh.advertiseService("pause", &MapRecorderNodelet::pauseCb, this);
  finish_srv_ = private_nh.advertiseService("finish", &MapRecorderNodelet::finishCb, this);

  const std::string params_topic = preprocessingParamsTopic(image_topic_);
  params_sub_ = nh.subscribe(params_topic, 1, &MapRecorderNodelet::paramsCb, this);
  odom_sub_ = nh.subscribe("odom", 10, &MapRecorderNodelet::odomCb, this);
  motion_type_ = readMotionType(private_nh, MotionType::kTwist, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  motion_topic_ = nh.resolveName("motion");  // before the subscription: its callback names it
  if (motion_type_ == MotionType::kTwist)
    motion_sub_ = nh.subscribe("motion", 100, &MapRecorderNodelet::motionTwistCb, this);
  else if (motion_type_ == MotionType::kOdometry)
    motion_sub_ = nh.subscribe("motion", 100, &MapRecorderNodelet::motionOdomCb, this);
  if (autostart)
    subscribeImages();
  diagnostics_timer_ = startDiagnosticsTimer(nh, updater_);
  NODELET_INFO("Recording %s into map %s (%s); preprocessing parameters from %s",
               image_topic_.c_str(), map_path_.c_str(),
               autostart ? "started" : "call ~start to begin", params_topic.c_str());
}

MapRecorderNodelet::~MapRecorderNodelet()
{
  if (!writer_thread_.joinable())
    return;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    stop_writer_ = true;
  }
  writer_cv_.notify_all();
  writer_thread_.join();
  const std::string lost = lossSentence();
  if (lost.empty())
    NODELET_INFO("%s", finish_message_.c_str());
  else
    NODELET_WARN("%s%s", finish_message_.c_str(), lost.c_str());
}

std::string MapRecorderNodelet::lossSentence() const
{
  if (refused_.count() == 0)
    return std::string();
  return "; not recorded: " + std::to_string(refused_.count()) + " of the " + std::to_string(frames_seen_) +
         " frames seen while recording (" + refused_.byKind("frame") + ")";
}

void MapRecorderNodelet::configCb(MapRecorderConfig& config, uint32_t /*level*/)
{
  std::vector<std::string> corrections = correctToTable(config, last_valid_config_);
  const ConfigReview review = reviewConfig(config, last_valid_config_, std::move(corrections), "");
  logConfigReview(review, getName(), "keyframe policy");
  policy_ = toPolicy(config);
}

void MapRecorderNodelet::paramsCb(const std_msgs::StringConstPtr& msg)
{
  std::string error;
  const std::shared_ptr<const PreprocessingParams> params = parseAnnouncedParameters(msg->data, &error);
  if (!params)
  {
    NODELET_ERROR("%s", error.c_str());
    return;
  }
  announced_params_ = params;
}

void MapRecorderNodelet::odomCb(const nav_msgs::OdometryConstPtr& msg)
{
  const geometry_msgs::Point& p = msg->pose.pose.position;
  if (have_odom_)
    distance_since_keyframe_m_ += std::sqrt((p.x - last_x_) * (p.x - last_x_) + (p.y - last_y_) * (p.y - last_y_) +
                                            (p.z - last_z_) * (p.z - last_z_));
  last_x_ = p.x;
  last_y_ = p.y;
  last_z_ = p.z;
  have_odom_ = true;
}

bool MapRecorderNodelet::recording()
{
  std::lock_guard<std::mutex> lock(queue_mutex_);
  return state_ == State::kRecording;
}

void MapRecorderNodelet::addMotion(double linear_mps, double angular_rps, bool recording)
{
  if (!std::isfinite(linear_mps) || !std::isfinite(angular_rps))
  {
    NODELET_WARN_THROTTLE(5.0, "Ignoring a motion message on %s with a non-finite velocity", motion_topic_.c_str());
    return;
  }
  ++motion_messages_;
  if (recording)
  {
    motion_sum_linear_ += linear_mps;
    motion_sum_angular_ += angular_rps;
    ++motion_count_;
  }
  latest_linear_ = linear_mps;
  latest_angular_ = angular_rps;
  latest_while_recording_ = recording;
}

void MapRecorderNodelet::motionTwistCb(const geometry_msgs::TwistConstPtr& msg)
{
  // A velocity command holds until the next one; a silence longer than 1 s is taken as standing still
  // (bases stop on a cmd_vel timeout), so it adds at most 1 s of the last speed.
  const ros::Time now = ros::Time::now();
  const bool recording_now = recording();
  if (recording_now && latest_while_recording_ && now > latest_motion_time_)
    motion_distance_m_ += std::fabs(latest_linear_) * std::min(1.0, (now - latest_motion_time_).toSec());
  latest_motion_time_ = now;
  addMotion(msg->linear.x, msg->angular.z, recording_now);
}

void MapRecorderNodelet::motionOdomCb(const nav_msgs::OdometryConstPtr& msg)
{
  const geometry_msgs::Point& p = msg->pose.pose.position;
  const bool recording_now = recording();
  if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
  {
    if (have_motion_pose_ && recording_now && latest_while_recording_)
      motion_distance_m_ += std::sqrt((p.x - motion_x_) * (p.x - motion_x_) + (p.y - motion_y_) * (p.y - motion_y_) +
                                      (p.z - motion_z_) * (p.z - motion_z_));
    motion_x_ = p.x;
    motion_y_ = p.y;
    motion_z_ = p.z;
    have_motion_pose_ = true;
  }
  addMotion(msg->twist.twist.linear.x, msg->twist.twist.angular.z, recording_now);
}

KeyframeMotionPtr MapRecorderNodelet::takeMotion(const std_msgs::Header& keyframe_header, bool first_keyframe)
{
  // Nothing heard while recording since the keyframe before (right after ~start or a resume, before the
  // first message): no record, rather than a velocity from before (the follower gives the keyframe the
  // nearest recorded one).
  if (motion_count_ == 0 && !latest_while_recording_)
    return KeyframeMotionPtr();
  KeyframeMotionPtr motion = boost::make_shared<KeyframeMotion>();
  motion->header = keyframe_header;
  motion->linear_mps = motion_count_ > 0 ? motion_sum_linear_ / motion_count_ : latest_linear_;
  motion->angular_rps = motion_count_ > 0 ? motion_sum_angular_ / motion_count_ : latest_angular_;
  motion->distance_m = first_keyframe ? 0.0 : motion_distance_m_;
  motion_sum_linear_ = motion_sum_angular_ = 0.0;
  motion_count_ = 0;
  motion_distance_m_ = 0.0;
  return motion;
}

bool MapRecorderNodelet::isKeyframe(const sensor_msgs::ImageConstPtr& msg, const KeyframePolicy& policy)
{
  ++frames_since_keyframe_;
  if (!last_keyframe_)
    return true;
  if (frames_since_keyframe_ < policy.every_nth)
    return false;
  if (policy.min_time_gap_s > 0.0)
  {
    const double gap_s = (msg->header.stamp - last_keyframe_->header.stamp).toSec();
    if (gap_s >= 0.0 && gap_s < policy.min_time_gap_s)  // a negative gap: time jumped back, take it
      return false;
  }
  if (policy.min_distance_m > 0.0)
  {
    if (!have_odom_)
    {
      NODELET_WARN_THROTTLE(10.0, "min_distance is %.2f m but no odometry arrived on %s: no keyframes are taken",
                            policy.min_distance_m, odom_sub_.getTopic().c_str());
      return false;
    }
    if (distance_since_keyframe_m_ < policy.min_distance_m)
      return false;
  }
  if (policy.min_appearance_change > 0.0)
  {
    const cv::Mat current = cv_bridge::toCvShare(msg)->image;
    const cv::Mat last = cv_bridge::toCvShare(last_keyframe_)->image;
    const double mean_change = cv::norm(current, last, cv::NORM_L1) / static_cast<double>(current.total());
    if (mean_change < policy.min_appearance_change)
      return false;
  }
  return true;
}

void MapRecorderNodelet::imageCb(const sensor_msgs::ImageConstPtr& msg)
{
  std::shared_ptr<const PreprocessingParams> recording_params;
  std::string writer_error;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    if (state_ != State::kRecording)
      return;
    writer_error = writer_error_;
    recording_params = recording_params_;
  }
  ++frames_seen_;
  if (!writer_error.empty())
  {
    if (refused_.drop(kWriterFailed, "not recording: " + writer_error))
      NODELET_ERROR("Not recording: %s", writer_error.c_str());
    return;
  }
  if (!announced_params_)
  {
    if (refused_.drop(kNoParameters, "waiting for the preprocessing parameters on " + params_sub_.getTopic() +
                                         " (is the preprocessor running?)"))
      NODELET_WARN("Waiting for the preprocessing parameters on %s (is the preprocessor running?); frames are not "
                   "recorded until they arrive",
                   params_sub_.getTopic().c_str());
    return;
  }
  if (recording_params && *recording_params != *announced_params_)
  {
    const std::string difference = preprocessingDifference(*recording_params, *announced_params_);
    if (refused_.drop(kParametersChanged, "the preprocessing parameters changed during the teach (" + difference +
                                              ")"))
      NODELET_ERROR("The preprocessing parameters changed during the teach (%s); a map holds one set, so these "
                    "frames are not recorded. Change them back, or ~finish and record another map",
                    difference.c_str());
    return;
  }
  if (msg->encoding != sensor_msgs::image_encodings::MONO8 ||
      static_cast<int>(msg->width) != announced_params_->output_width ||
      static_cast<int>(msg->height) != announced_params_->output_height ||
      msg->step < msg->width || msg->data.size() < static_cast<size_t>(msg->step) * msg->height)
  {
    char sentence[256];
    std::snprintf(sentence, sizeof(sentence), "a %ux%u '%s' frame: the preprocessing parameters make %dx%d mono8",
                  msg->width, msg->height, msg->encoding.c_str(), announced_params_->output_width,
                  announced_params_->output_height);
    if (refused_.drop(kWrongSize, sentence))
      NODELET_ERROR("Dropping %s", sentence);
    return;
  }

  if (last_keyframe_ && !msg->header.stamp.isZero() && !last_keyframe_->header.stamp.isZero() &&
      msg->header.stamp <= last_keyframe_->header.stamp)
  {
    // Time went back (a looping `rosbag play`, a restarted clock): the map holds that time already. Taken,
    // a loop recorded the route again after its end, and the repeat found every place more than once.
    char sentence[160];
    std::snprintf(sentence, sizeof(sentence),
                  "a frame stamped %.3f s, not after the last keyframe's %.3f s (time went back: a looping bag?)",
                  msg->header.stamp.toSec(), last_keyframe_->header.stamp.toSec());
    if (refused_.drop(kTimeWentBack, sentence))
      NODELET_WARN("Not recording frames stamped before the last keyframe (%.3f s, not after %.3f s): time went "
                   "back (a looping bag, a restarted clock?). The map keeps the drive so far; ~finish it, and "
                   "record another map for another drive",
                   msg->header.stamp.toSec(), last_keyframe_->header.stamp.toSec());
    return;
  }
  KeyframePolicy policy;
  {
    std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
    policy = policy_;
  }
  if (!isKeyframe(msg, policy))
  {
    refused_.used();  // seen, and not a keyframe by the policy
    return;
  }
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    if (queue_.size() >= max_queue_)
    {
      const std::string sentence =
          "the map writer is " + std::to_string(queue_.size()) + " keyframes behind (disk too slow?)";
      if (refused_.drop(kWriterBehind, sentence))
        NODELET_ERROR("Dropping keyframes: %s", sentence.c_str());
      return;
    }
    if (!recording_params_)
      recording_params_ = announced_params_;
    QueuedKeyframe keyframe;
    keyframe.image = msg;
    keyframe.motion = takeMotion(msg->header, keyframes_queued_ == 0);
    if (keyframe.motion)
      ++keyframes_with_motion_;
    queue_.push_back(keyframe);
    ++keyframes_queued_;
  }
  writer_cv_.notify_one();
  refused_.used();
  last_keyframe_ = msg;
  frames_since_keyframe_ = 0;
  distance_since_keyframe_m_ = 0.0;
}

void MapRecorderNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  using diagnostic_msgs::DiagnosticStatus;
  State state;
  size_t queued, written, backlog;
  std::string writer_error, finish_message;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    state = state_;
    queued = keyframes_queued_;
    written = keyframes_written_;
    backlog = queue_.size();
    writer_error = writer_error_;
    finish_message = finish_message_;
  }
  static const char* const kStates[] = { "idle", "recording", "paused", "finished" };
  const std::string keyframes = std::to_string(queued) + (queued == 1 ? " keyframe" : " keyframes");
  std::string transport_error;
  {
    std::lock_guard<std::mutex> lock(image_sub_mutex_);
    transport_error = transport_error_;
  }
  // Keyframes taken while recording and no motion message yet, the motion topic of another type: roscpp says so
  // only in the publisher's log, and the follower refuses such a map later. (No publisher at all is a teach
  // without motion, which localizes: not said.)
  std::string motion_problem;
  if (state == State::kRecording && motion_sub_ && motion_messages_ == 0 && queued > 0)
  {
    motion_problem = motionTopicTypeProblem(motion_topic_, motion_type_);
    if (!motion_problem.empty() && !motion_type_warned_)
    {
      NODELET_ERROR("The keyframes get no taught motion: %s", motion_problem.c_str());
      motion_type_warned_ = true;
    }
  }
  if (map_path_.empty())
    stat.summary(DiagnosticStatus::ERROR, "no ~map parameter: nothing is recorded");
  else if (!transport_error.empty())
    stat.summary(DiagnosticStatus::ERROR, "not recording: no images from " + image_topic_ + ": " + transport_error);
  else if (!writer_error.empty())
    stat.summary(DiagnosticStatus::ERROR, "not recording: " + writer_error);
  else if (state == State::kFinished)
    stat.summary(refused_.count() > 0 ? DiagnosticStatus::WARN : DiagnosticStatus::OK,
                 finish_message.empty() ? std::string("finishing") : "finished: " + finish_message + lossSentence());
  else if (state == State::kIdle)
    stat.summary(DiagnosticStatus::OK, "idle: call ~start to record");
  else if (state == State::kPaused)
    stat.summary(DiagnosticStatus::OK, "paused after " + keyframes);
  // Frames refused for a writer failure: said by the branch above while it lasts, not news once it is over.
  else if (refused_.newestDropped() && refused_.lastKind() != kWriterFailed)
    stat.summary(refused_.lastKind() == kNoParameters ? DiagnosticStatus::WARN : DiagnosticStatus::ERROR,
                 "not recording the frames: " + refused_.lastReason());
  else if (frames_seen_ == 0)
    stat.summary(DiagnosticStatus::WARN, "recording, waiting for images on " + image_topic_);
  else if (!motion_problem.empty())
    stat.summary(DiagnosticStatus::WARN, "recording: " + keyframes + ", without taught motion: " + motion_problem);
  else
    stat.summary(DiagnosticStatus::OK, "recording: " + keyframes);
  stat.add("map", map_path_.empty() ? std::string("(none)") : map_path_);
  stat.add("state", kStates[static_cast<int>(state)]);
  stat.add("frames seen while recording", frames_seen_);
  stat.add("keyframes taken", queued);
  stat.add("keyframes written", written);
  stat.add("keyframes waiting for the writer", backlog);
  stat.add("motion topic", motion_sub_.getTopic());
  stat.add("motion messages", motion_messages_);
  stat.add("keyframes with motion", keyframes_with_motion_);
  refused_.addTo(stat, "frame");
}

void MapRecorderNodelet::subscribeImages()
{
  std::lock_guard<std::mutex> lock(image_sub_mutex_);
  if (image_sub_ || !transport_error_.empty())
    return;
  image_sub_ = subscribeTransported(*it_, "image_preprocessed", image_queue_size_, &MapRecorderNodelet::imageCb, this,
                                    getPrivateNodeHandle(), &transport_error_);
  if (!transport_error_.empty())
    NODELET_ERROR("Nothing will be recorded: images on %s: %s", image_topic_.c_str(), transport_error_.c_str());
}

bool MapRecorderNodelet::startCb(std_srvs::Trigger::Request& /*req*/, std_srvs::Trigger::Response& res)
{
  // What would make ~finish fail is said now: before the first keyframe, the target is checked again (a
  // `.active` left by an interrupted recording may have come, or gone, since the nodelet was loaded).
  bool nothing_taken;
  {
    std::lock_guard<std::mutex> lock(queue_mutex_);
    nothing_taken = keyframes_queued_ == 0;
  }
  std::string target_error;
  if (!map_path_.empty() && nothing_taken)
  {
    try
    {
      requireAbsoluteMapPath(map_path_);
      checkMapTarget(map_path_);
    }
    catch (const MapError& e)
    {
      target_error = e.what();
    }
  }
  std::unique_lock<std::mutex> lock(queue_mutex_);
  if (nothing_taken && keyframes_queued_ == 0)
    writer_error_ = target_error;  // before any keyframe, only the target can have failed
  std::string transport_error;
  {
    std::lock_guard<std::mutex> image_lock(image_sub_mutex_);
    transport_error = transport_error_;
  }
  if (map_path_.empty())
  {
    res.success = false;
    res.message = "no ~map parameter: nothing can be recorded";
  }
  else if (!transport_error.empty())
  {
    res.success = false;
    res.message = "cannot take images from " + image_topic_ + ": " + transport_error;
  }
  else if (state_ == State::kFinished)
  {
    res.success = false;
    res.message = "the recording of " + map_path_ + " is finished; load the nodelet again to record another map";
  }
  else if (!writer_error_.empty())
  {
    res.success = false;
    res.message = "cannot record " + map_path_ + ": " + writer_error_;
  }
  else
  {
    res.success = true;
    res.message = std::string(state_ == State::kPaused    ? "resumed recording " :
                              state_ == State::kRecording ? "already recording " :
                                                            "started recording ") +
                  map_path_;
    state_ = State::kRecording;
  }
  lock.unlock();  // subscribing talks to the master: not while the writer thread and ~finish wait for the lock
  if (res.success)
  {
    subscribeImages();
    NODELET_INFO("~start: %s", res.message.c_str());
  }
  else
  {
    NODELET_ERROR("~start: %s", res.message.c_str());
  }
  return true;
}

bool MapRecorderNodelet::pauseCb(std_srvs::Trigger::Request& /*req*/, std_srvs::Trigger::Response& res)
{
  std::lock_guard<std::mutex> lock(queue_mutex_);
  res.success = state_ == State::kRecording;
  if (res.success)
  {
    state_ = State::kPaused;
    latest_while_recording_ = false;  // a silent motion topic: the interval across the pause is not taught
    res.message = "paused after " + std::to_string(keyframes_queued_) + " keyframes";
  }
  else
  {
    res.message = "not recording";
  }
  NODELET_INFO("~pause: %s", res.message.c_str());
  return true;
}

bool MapRecorderNodelet::finishCb(std_srvs::Trigger::Request& /*req*/, std_srvs::Trigger::Response& res)
{
  std::unique_lock<std::mutex> lock(queue_mutex_);
  if (map_path_.empty())
  {
    res.success = false;
    res.message = "no ~map parameter: nothing was recorded";
    return true;
  }
  if (state_ != State::kFinished)
  {
    state_ = State::kFinished;
    finish_requested_ = true;
    writer_cv_.notify_all();
  }
  // Waits for the writer thread (a flush takes milliseconds), bounded in case the disk hangs.
  if (!finished_cv_.wait_for(lock, std::chrono::seconds(30), [this] { return finish_done_; }))
  {
    res.success = false;
    res.message = "the map writer did not finish within 30 s; " + map_path_ + " holds the last flush";
  }
  else
  {
    res.success = writer_error_.empty() && keyframes_written_ > 0;
    res.message = finish_message_;
  }
  const bool no_keyframe_has_motion = res.success && motion_sub_ && keyframes_with_motion_ == 0;
  const std::string lost = lossSentence();
  lock.unlock();  // the master is asked below: not while the writer thread and the callbacks wait
  res.message += lost;
  const std::string motion_problem =
      no_keyframe_has_motion ? motionTopicTypeProblem(motion_topic_, motion_type_) : std::string();
  if (!motion_problem.empty())
    res.message += "; no keyframe has taught motion (" + motion_problem +
                   "): it localizes, but the route follower refuses it";
  if (res.success && lost.empty() && motion_problem.empty())
    NODELET_INFO("~finish: %s", res.message.c_str());
  else
    NODELET_WARN("~finish: %s", res.message.c_str());
  return true;
}

void MapRecorderNodelet::writerLoop()
{
  std::unique_ptr<MapWriter> writer;
  std::string last_logged_error;
  auto next_flush = std::chrono::steady_clock::now() + std::chrono::duration<double>(flush_period_s_);
  std::unique_lock<std::mutex> lock(queue_mutex_);
  while (true)
  {
    writer_cv_.wait_until(lock, next_flush,
                          [this] { return stop_writer_ || finish_requested_ || !queue_.empty(); });
    std::deque<QueuedKeyframe> batch;
    batch.swap(queue_);
    const bool stop = stop_writer_;
    const bool finish = finish_requested_ || stop_writer_;
    const std::shared_ptr<const PreprocessingParams> params = recording_params_;
    lock.unlock();

    std::string error;
    bool wrote = false;  // a flush went through: an earlier failure (a full disk) is over
    const auto now = std::chrono::steady_clock::now();
    try
    {
      if (!batch.empty() && !writer)
        writer.reset(new MapWriter(map_path_, *params, "recorder=" + getName()));
      for (const QueuedKeyframe& keyframe : batch)
        writer->add(keyframe.image, keyframe.motion);
      if (writer && (finish || now >= next_flush))
      {
        if (finish)
          writer->close();
        else
          writer->flush();
        wrote = true;
      }
    }
    catch (const std::exception& e)  // MapError, and anything else rosbag throws: never out of the thread
    {
      error = e.what();
      if (error != last_logged_error)  // a failing flush fails again every flush_period: said once
        NODELET_ERROR("Map %s: %s", map_path_.c_str(), error.c_str());
      last_logged_error = error;
    }
    // Also after a failed flush: retried at the next period, not at once (it failed 125 804 times in 6.6 s,
    // the manager at full CPU, the log growing by megabytes a second).
    if (now >= next_flush)
      next_flush = now + std::chrono::duration<double>(flush_period_s_);

    lock.lock();
    if (writer)
    {
      keyframes_written_ = writer->written();
      replaced_path_ = writer->replacedPath();
    }
    if (!error.empty())
      writer_error_ = error;
    else if (wrote && !writer_error_.empty())
    {
      NODELET_INFO("Map %s: written again (%zu keyframes); recording goes on", map_path_.c_str(), keyframes_written_);
      writer_error_.clear();
      last_logged_error.clear();
    }
    if (finish && !finish_done_)
    {
      if (!writer_error_.empty())
        finish_message_ = "map " + map_path_ + " failed: " + writer_error_ +
                          (keyframes_queued_ > keyframes_written_ ?
                               "; " + std::to_string(keyframes_queued_ - keyframes_written_) + " of the " +
                                   std::to_string(keyframes_queued_) + " keyframes taken were not written" :
                               std::string());
      else if (keyframes_written_ == 0)
        finish_message_ = "no keyframes were recorded; no map written to " + map_path_;
      else
        finish_message_ = "map " + map_path_ + " holds " + std::to_string(keyframes_written_) + " keyframes" +
                          (replaced_path_.empty() ? std::string() :
                                                    "; the map that was there before is kept as " + replaced_path_);
      finish_requested_ = false;
      finish_done_ = true;
      state_ = State::kFinished;
      writer.reset();
      finished_cv_.notify_all();
    }
    if (stop)
      break;
  }
}

}  // namespace along_route_localization

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(along_route_localization::MapRecorderNodelet, nodelet::Nodelet)
