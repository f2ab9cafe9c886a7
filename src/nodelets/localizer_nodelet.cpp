// Repeat: localizes each preprocessed frame against the route map with the core Localizer.
//
// Subscribes: image_preprocessed (mono8, queue 1: the newest frame wins)
//             <namespace of image_preprocessed>/preprocessing_params (latched, from the preprocessor):
//             a map made with other parameters is refused
//             motion (optional, with ~motion_type twist or odometry: geometry_msgs/Twist, e.g. the robot's
//             cmd_vel, or nav_msgs/Odometry): whether the robot stood still between two frames
//             (StandstillDetector); a featureless frame taken while it stood changes nothing (Localizer::process)
// Publishes:  localization (along_route_localization/Localization, header copied from the image)
//             localization_debug_image (bgr8, only while subscribed: the ring buffer with the path, debug_image.h)
//             /diagnostics (processing time per frame, rate, status, frames dropped and why)
// Services:   ~load_map (along_route_localization/LoadMap)
// Parameters: ~map (absolute path, loaded at start), ~motion_type (none | twist | odometry; none: no motion
//             topic), ~debug_image_scale (8), ~min_rate / ~max_rate (Hz,
//             expected input rate for diagnostics); cfg/Localizer.cfg (dynamic, applied between
//             frames); any other localizer parameter of the parameter table (static, e.g. ~cost_function)
// Test hook: ~report_input_buffer (false): publishes on ~input_buffer (std_msgs/String) the address of
//             the pixels the core read, "<pointer> @ <sec>.<nsec>", for the zero-copy test only.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <boost/thread/recursive_mutex.hpp>
#include <cv_bridge/cv_bridge.h>
#include <diagnostic_updater/diagnostic_updater.h>
#include <diagnostic_updater/update_functions.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/Twist.h>
#include <image_transport/image_transport.h>
#include <nav_msgs/Odometry.h>
#include <nodelet/nodelet.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>

#include "along_route_localization/LoadMap.h"
#include "along_route_localization/Localization.h"
#include "along_route_localization/LocalizerConfig.h"
#include "along_route_localization/debug_image.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/parameters.h"
#include "glue/diagnostics.h"
#include "glue/image_subscription.h"
#include "glue/map_io.h"
#include "glue/private_parameters.h"
#include "glue/reconfigure.h"

namespace along_route_localization
{

class LocalizerNodelet : public nodelet::Nodelet
{
private:
  void onInit() override;
  void imageCb(const sensor_msgs::ImageConstPtr& msg);
  void paramsCb(const std_msgs::StringConstPtr& msg);
  void motionTwistCb(const geometry_msgs::TwistConstPtr& msg);
  void motionOdomCb(const nav_msgs::OdometryConstPtr& msg);
  void configCb(LocalizerConfig& config, uint32_t level);
  bool loadMapCb(LoadMap::Request& req, LoadMap::Response& res);
  bool loadMap(const std::string& path, std::string* message);
  void useMapIfAccepted();
  LocalizerParams staticParams(const ros::NodeHandle& private_nh);
  void warnAboutUnreadParameters(const ros::NodeHandle& private_nh);
  LocalizerParams effectiveParams(const LocalizerParams& requested) const;
  void publishDebugImage(const std_msgs::Header& header, const LocalizationResult& result);
  /// Kinds of reason not to localize a frame (DroppedFrames logs each kind apart).
  enum Drop
  {
    kRefusedMap,
    kEncoding,
    kSize,
    kFailure
  };
  /// Counts the frame as dropped for the diagnostics and logs why, throttled per kind.
  void dropFrame(Drop kind, const std::string& sentence);
  /// Subscribes to the preprocessed images once a map is loaded (and the image transport is up): without a
  /// map every frame would be dropped, and a camera played with `rosbag play --wait-for-subscribers` waits
  /// for the subscription (the preprocessor subscribes to the camera only while someone listens to it).
  void subscribeImages();
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  // Static parameters, read in onInit.
  int debug_image_scale_ = 8;
  double min_rate_hz_ = 1.0, max_rate_hz_ = 1000.0;

  std::shared_ptr<image_transport::ImageTransport> it_;
  image_transport::Subscriber image_sub_;  // from the first map loaded on (subscribeImages)
  std::string transport_error_;            // why images cannot be subscribed to (a missing plugin), or ""
  std::string image_topic_;                // its resolved name
  image_transport::Publisher debug_pub_;
  ros::Subscriber params_sub_;
  ros::Subscriber motion_sub_;  // only with ~motion_type twist or odometry
  ros::Publisher localization_pub_;
  ros::Publisher input_buffer_pub_;  // the zero-copy test's hook; only with ~report_input_buffer
  ros::ServiceServer load_map_srv_;
  std::shared_ptr<diagnostic_updater::Updater> updater_;
  std::shared_ptr<diagnostic_updater::FrequencyStatus> rate_status_;
  ros::WallTimer diagnostics_timer_;

  // Written by configCb, copied by imageCb; guarded by config_mutex_ (also the server's mutex).
  boost::recursive_mutex config_mutex_;
  std::shared_ptr<dynamic_reconfigure::Server<LocalizerConfig>> reconfigure_server_;
  LocalizerConfig last_valid_config_;
  LocalizerParams requested_params_;
  bool params_changed_ = false;
  int map_width_ = 0;  // of the loaded map, to bound max_shift_px; 0 while none

  // Used only from the nodelet's single-threaded callback queue (images, parameters, the service and
  // the diagnostics timer), so nothing here needs a lock.
  LocalizerParams params_;  // the ones in use
  std::shared_ptr<const RouteMap> map_;
  std::string map_path_;
  std::string map_error_;  // why no map is loaded
  std::shared_ptr<const PreprocessingParams> announced_;
  std::unique_ptr<Localizer> localizer_;  // null while there is no accepted map
  std::string refusal_;                   // why the loaded map is not used
  bool unchecked_warned_ = false;
  ros::Time last_stamp_;
  // A frame of this map's drive was localized: a restart (a refused map accepted again) is then in the
  // middle of the drive, and does not assume the route start.
  bool drive_localized_ = false;
  ros::Time last_frame_received_;  // ROS time when the last frame was localized (loadMap: mid-drive or not)
  bool resumed_mid_drive_ = false;  // restarted so, and no frame processed since
  LocalizationResult last_result_;
  StandstillDetector standstill_;  // the motion topic's samples; used only when motion_sub_ is set
  uint64_t frames_ = 0, frames_in_period_ = 0, resets_ = 0;
  FrameGapCounts gaps_;
  DroppedFrames dropped_;
  double time_sum_ms_ = 0.0, time_max_ms_ = 0.0, last_time_ms_ = 0.0;
  double busy_s_ = 0.0;        // wall time of the last image callback, parameter changes included
  bool changed_last_ = false;  // whether that callback applied a parameter change
};

namespace
{

uint8_t toMsgStatus(LocalizationStatus status)
{
  switch (status)
  {
    case LocalizationStatus::kInitializing:
      return Localization::STATUS_INITIALIZING;
    case LocalizationStatus::kTracking:
      return Localization::STATUS_TRACKING;
    case LocalizationStatus::kLost:
      return Localization::STATUS_LOST;
    case LocalizationStatus::kEndOfRoute:
      return Localization::STATUS_END_OF_ROUTE;
  }
  return Localization::STATUS_LOST;
}

int largestShiftFor(int width)
{
  return std::max(0, (width - 1) / 2);  // leaves a compared strip of at least one column
}

}  // namespace

LocalizerParams LocalizerNodelet::staticParams(const ros::NodeHandle& private_nh)
{
  // Every core parameter not in Localizer.cfg can still be set once, under the same name that
  // params.yaml and localize_offline use (the parameter table), e.g. ~cost_function, ~min_texture_ratio.
  // Localizer.cfg's own parameters are dynamic_reconfigure's (onInit).
  static const std::set<std::string> dynamic = configParameterNames<LocalizerConfig>();
  // Each value checked against its working range first: corrected (a number outside it) or refused (a
  // value that does not parse), and named either way; the others are taken.
  // The window's rows are dynamic, but min_init_frames must not exceed them: checked with the value given
  // (when it is valid with the defaults; configCb corrects it otherwise).
  LocalizerParams base, with_rows;
  if (private_nh.getParam("ring_buffer_rows", with_rows.ring_buffer_rows) && with_rows.validate().empty())
    base = with_rows;
  ParameterSet checked;
  checked.localizer = base;
  std::vector<std::pair<std::string, std::string>> given;
  for (const std::string& name : localizerParameterNames())
  {
    XmlRpc::XmlRpcValue value;
    if (dynamic.count(name) || !private_nh.getParam(name, value))
      continue;
    bool refused = false;
    const std::string sentence = setParameterChecked(name, parameterText(value, 17), &checked, &refused);
    if (!sentence.empty())
      NODELET_WARN("~%s", sentence.c_str());
    if (!refused)
      given.emplace_back(name, findParameter(name)->valueText(checked));
  }
  // Each static value used other than its default, once at INFO, as configCb says each dynamic one.
  const auto say_used = [this](const LocalizerParams& used) {
    ParameterSet in_use;
    in_use.localizer = used;
    for (const ParameterSpec& spec : parameterTable())
      if (spec.group == ParameterGroup::kLocalizer && !dynamic.count(spec.name) &&
          spec.valueText(in_use) != spec.defaultText())
        NODELET_INFO("%s %s -> %s", spec.name.c_str(), spec.defaultText().c_str(), spec.valueText(in_use).c_str());
    return used;
  };
  if (checked.localizer.validate().empty())
    return say_used(checked.localizer);
  // Some are valid only together (seqslam_min_velocity <= seqslam_max_velocity): one at a time, in passes
  // until none is taken (a value refused beside one default may be valid beside another given value);
  // each value never taken is named.
  PreprocessingParams ignored;  // the preprocessor's business
  std::string error;
  LocalizerParams params = base;
  std::vector<bool> taken(given.size(), false);
  for (bool progress = true; progress;)
  {
    progress = false;
    for (size_t i = 0; i < given.size(); ++i)
    {
      LocalizerParams candidate = params;
      if (!taken[i] && applyParameter(given[i].first, given[i].second, &ignored, &candidate, &error) &&
          candidate.validate().empty())
      {
        params = candidate;
        taken[i] = progress = true;
      }
    }
  }
  for (size_t i = 0; i < given.size(); ++i)
  {
    LocalizerParams candidate = params;
    if (taken[i] || !applyParameter(given[i].first, given[i].second, &ignored, &candidate, &error))
      continue;
    NODELET_ERROR("Ignoring ~%s = %s: %s; keeping %s", given[i].first.c_str(), given[i].second.c_str(),
                  candidate.validate().c_str(), findParameter(given[i].first)->defaultText().c_str());
  }
  return say_used(params);
}

void LocalizerNodelet::warnAboutUnreadParameters(const ros::NodeHandle& private_nh)
{
  std::set<std::string> read = configParameterNames<LocalizerConfig>();
  for (const std::string& name : localizerParameterNames())
    read.insert(name);
  const std::set<std::string>& own = nodeletSettingNames(ParameterGroup::kLocalizer);
  read.insert(own.begin(), own.end());
  const std::vector<std::string> preprocessing = preprocessingParameterNames();
  for (const std::string& name : unreadParameters(private_nh, read))
  {
    if (std::find(preprocessing.begin(), preprocessing.end(), name) != preprocessing.end())
      NODELET_WARN("~%s is not read here: it is the preprocessor's parameter, and the localizer takes the "
                   "preprocessing from the map",
                   name.c_str());
    else
      NODELET_WARN("%s", unreadSentence(name, "localizer", read).c_str());
  }
}

void LocalizerNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& private_nh = getPrivateNodeHandle();

  warnAboutUnreadParameters(private_nh);
  std::string problem;
  debug_image_scale_ = readIntParameter(private_nh, "debug_image_scale", debug_image_scale_, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (debug_image_scale_ < 1 || debug_image_scale_ > 64)
  {
    NODELET_ERROR("~debug_image_scale must be 1 to 64 (%d); using 8", debug_image_scale_);
    debug_image_scale_ = 8;
  }
  min_rate_hz_ = readDoubleParameter(private_nh, "min_rate", min_rate_hz_, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  max_rate_hz_ = readDoubleParameter(private_nh, "max_rate", max_rate_hz_, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (!(min_rate_hz_ >= 0.0 && max_rate_hz_ >= min_rate_hz_ && std::isfinite(max_rate_hz_)))
  {
    NODELET_ERROR("~min_rate and ~max_rate must satisfy 0 <= min_rate <= max_rate (%g, %g Hz); using 1 and 1000",
                  min_rate_hz_, max_rate_hz_);
    min_rate_hz_ = 1.0;
    max_rate_hz_ = 1000.0;
  }
  // Before staticParams, which reads ~ring_buffer_rows too: a mistyped value is replaced by the default first.
  for (const std::string& sentence : mistypedParameters<LocalizerConfig>(private_nh))
    NODELET_WARN("%s", sentence.c_str());
  requested_params_ = staticParams(private_nh);

  last_valid_config_ = LocalizerConfig::__getDefault__();
  reconfigure_server_ = std::make_shared<dynamic_reconfigure::Server<LocalizerConfig>>(config_mutex_, private_nh);
  reconfigure_server_->setCallback([this](LocalizerConfig& config, uint32_t level) { configCb(config, level); });
  {
    std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
    params_ = requested_params_;
    params_changed_ = false;
  }

  image_topic_ = nh.resolveName("image_preprocessed");  // before the diagnostics timer reads it
  const std::string path = readStringParameter(private_nh, "map", std::string(), &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (path.empty())
  {
    map_error_ = "no map loaded: set ~map or call ~load_map";
    NODELET_WARN("No ~map parameter; waiting for a map through %s", private_nh.resolveName("load_map").c_str());
  }
  else
  {
    std::string message;
    loadMap(path, &message);
  }

  updater_ = std::make_shared<diagnostic_updater::Updater>(nh, private_nh, getName());
  updater_->setHardwareID("none");
  rate_status_ = std::make_shared<diagnostic_updater::FrequencyStatus>(
      diagnostic_updater::FrequencyStatusParam(&min_rate_hz_, &max_rate_hz_), "localization rate");
  updater_->add(*rate_status_);
  updater_->add("localization", this, &LocalizerNodelet::diagnose);
  diagnostics_timer_ = startDiagnosticsTimer(nh, updater_);

  localization_pub_ = nh.advertise<Localization>("localization", 10);
  const bool report_input_buffer = readBoolParameter(private_nh, "report_input_buffer", false, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (report_input_buffer)
    input_buffer_pub_ = private_nh.advertise<std_msgs::String>("input_buffer", 100);
  it_ = std::make_shared<image_transport::ImageTransport>(nh);
  debug_pub_ = it_->advertise("localization_debug_image", 1);
  transport_error_ = transportProblem(private_nh);  // said now, not only once a map is loaded
  if (!transport_error_.empty())
    NODELET_ERROR("Images on %s: %s", image_topic_.c_str(), transport_error_.c_str());
  // The same single-threaded queue as the images: the detector needs no lock. Before the images are
  // subscribed: imageCb reads motion_sub_, and callbacks may run while onInit goes on.
  const MotionType motion_type = readMotionType(private_nh, MotionType::kNone, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s: the images alone tell whether the robot stood still", problem.c_str());
  if (motion_type == MotionType::kTwist)
    motion_sub_ = nh.subscribe("motion", 100, &LocalizerNodelet::motionTwistCb, this);
  else if (motion_type == MotionType::kOdometry)
    motion_sub_ = nh.subscribe("motion", 100, &LocalizerNodelet::motionOdomCb, this);
  if (motion_sub_)
    NODELET_INFO("Whether the robot stood still between frames: from %s (%s)", motion_sub_.getTopic().c_str(),
                 motionTypeName(motion_type).c_str());
  const std::string params_topic = preprocessingParamsTopic(image_topic_);
  params_sub_ = nh.subscribe(params_topic, 1, &LocalizerNodelet::paramsCb, this);
  if (map_)
    subscribeImages();
  // After the subscription: a map loaded through it subscribes from the service's callback (loadMap).
  load_map_srv_ = private_nh.advertiseService("load_map", &LocalizerNodelet::loadMapCb, this);
  NODELET_INFO("Localizing %s against %s; preprocessing parameters checked against %s",
               image_topic_.c_str(), map_ ? map_path_.c_str() : "(no map yet)",
               params_topic.c_str());
}

void LocalizerNodelet::motionTwistCb(const geometry_msgs::TwistConstPtr& msg)
{
  standstill_.velocity(msg->linear.x, ros::Time::now().toSec());  // a Twist has no stamp: when it came
}

void LocalizerNodelet::motionOdomCb(const nav_msgs::OdometryConstPtr& msg)
{
  const ros::Time stamp = msg->header.stamp.isZero() ? ros::Time::now() : msg->header.stamp;
  standstill_.velocity(msg->twist.twist.linear.x, stamp.toSec());
}

void LocalizerNodelet::configCb(LocalizerConfig& config, uint32_t /*level*/)
{
  // Corrections, so the panel shows the values in use: each value into its working range, then the
  // combinations.
  std::vector<std::string> corrections = correctToTable(config, last_valid_config_);
  char sentence[256];
  if (config.search_radius < config.max_step)
  {
    std::snprintf(sentence, sizeof(sentence), "search_radius %d is below max_step %d; using %d", config.search_radius,
                  config.max_step, config.max_step);
    corrections.push_back(sentence);
    config.search_radius = config.max_step;
  }
  if (config.ring_buffer_rows < requested_params_.min_init_frames)
  {
    std::snprintf(sentence, sizeof(sentence),
                  "ring_buffer_rows %d is below min_init_frames %d (a global search would never answer); using %d",
                  config.ring_buffer_rows, requested_params_.min_init_frames, requested_params_.min_init_frames);
    corrections.push_back(sentence);
    config.ring_buffer_rows = requested_params_.min_init_frames;
  }
  if (config.lost_window_frames < config.lost_after_frames)
  {
    std::snprintf(sentence, sizeof(sentence), "lost_window_frames %d is below lost_after_frames %d; using %d",
                  config.lost_window_frames, config.lost_after_frames, config.lost_after_frames);
    corrections.push_back(sentence);
    config.lost_window_frames = config.lost_after_frames;
  }
  if (map_width_ > 0 && config.max_shift_px > largestShiftFor(map_width_))
  {
    std::snprintf(sentence, sizeof(sentence), "max_shift_px %d leaves nothing to compare in %d px wide images; using %d",
                  config.max_shift_px, map_width_, largestShiftFor(map_width_));
    corrections.push_back(sentence);
    config.max_shift_px = largestShiftFor(map_width_);
  }
  std::string invalid;
  const LocalizerParams params = toParams(config, requested_params_, &invalid);
  if (invalid.empty())
    invalid = params.validate();
  const ConfigReview review = reviewConfig(config, last_valid_config_, std::move(corrections), invalid);
  logConfigReview(review, getName(), "localizer parameters");
  if (!review.rejected.empty())
    return;
  requested_params_ = params;
  params_changed_ = true;
}

LocalizerParams LocalizerNodelet::effectiveParams(const LocalizerParams& requested) const
{
  LocalizerParams params = requested;
  if (map_ && params.max_shift_px > largestShiftFor(map_->width()))
    params.max_shift_px = largestShiftFor(map_->width());
  // A start beyond this map (e.g. given for another map): unknown, a global search (useMapIfAccepted says so).
  if (map_ && params.start_keyframe >= static_cast<int>(map_->size()))
    params.start_keyframe = -1;
  return params;
}

bool LocalizerNodelet::loadMapCb(LoadMap::Request& req, LoadMap::Response& res)
{
  std::string message;
  res.success = loadMap(req.path, &message);
  res.message = message;
  res.keyframes = res.success ? static_cast<uint32_t>(map_->size()) : 0;
  return true;
}

bool LocalizerNodelet::loadMap(const std::string& path, std::string* message)
{
  std::shared_ptr<const RouteMap> map;
  try
  {
    requireAbsoluteMapPath(path);
    map = std::make_shared<const RouteMap>(readMap(path));
  }
  catch (const MapError& e)
  {
    *message = e.what();
    if (!map_)
      map_error_ = *message;
    NODELET_ERROR("%s%s", message->c_str(), map_ ? "; keeping the current map" :
                                                 "; waiting for ~load_map (not listening to images until then)");
    return false;
  }
  if (announced_ && *announced_ != map->params())
  {
    *message = "map " + path + " was made with other preprocessing parameters than the preprocessor's (" +
               preprocessingDifference(map->params(), *announced_) + ", map vs preprocessor); refused";
    if (!map_)
      map_error_ = *message;
    NODELET_ERROR("%s", message->c_str());
    return false;
  }
  map_ = map;
  map_path_ = path;
  map_error_.clear();
  subscribeImages();
  {
    std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
    map_width_ = map_->width();
  }
  localizer_.reset();
  // Mid-drive (a frame localized within the period of ~min_rate, the slowest camera expected): the robot is
  // somewhere along the route, not at start_keyframe, so the new map starts from an unknown place (a global
  // search), as after a refusal mid-drive; a next drive (stamps going back) starts at start_keyframe. It
  // restarted at start_keyframe: a repeat at keyframe 56 answered keyframes 0-35 at "tracking" for 3.5 s.
  const double since_last_frame_s = (ros::Time::now() - last_frame_received_).toSec();
  const bool mid_drive = drive_localized_ && !last_frame_received_.isZero() &&
                         (min_rate_hz_ <= 0.0 || since_last_frame_s <= 1.0 / min_rate_hz_);
  drive_localized_ = mid_drive;
  resumed_mid_drive_ = false;
  useMapIfAccepted();
  if (!localizer_)
  {
    *message = refusal_;
    return false;
  }
  if (!mid_drive)
    last_stamp_ = ros::Time();  // mid-drive it is kept: a stamp before it is a next drive, from the start
  *message = "loaded " + path + ": " + std::to_string(map_->size()) + " keyframes of " +
             std::to_string(map_->width()) + "x" + std::to_string(map_->height()) + " px" +
             (mid_drive ? "; localizing from an unknown place (a global search), since it was loaded mid-drive" : "");
  NODELET_INFO("%s", message->c_str());
  return true;
}

void LocalizerNodelet::subscribeImages()
{
  if (image_sub_ || !it_ || !transport_error_.empty())  // a missing transport plugin: a new load tries again
    return;
  std::string error;
  image_sub_ = subscribeTransported(*it_, "image_preprocessed", 1, &LocalizerNodelet::imageCb, this,
                                    getPrivateNodeHandle(), &error);
  if (!error.empty())
    NODELET_ERROR("Images on %s: %s", image_topic_.c_str(), error.c_str());
  transport_error_ = error;
}

void LocalizerNodelet::useMapIfAccepted()
{
  if (!map_)
    return;
  if (announced_ && *announced_ != map_->params())
  {
    const std::string refusal = "map " + map_path_ + " was made with other preprocessing parameters than the " +
                                "preprocessor's (" + preprocessingDifference(map_->params(), *announced_) +
                                ", map vs preprocessor); refused until they match or another map is loaded";
    if (localizer_ || refusal != refusal_)
      NODELET_ERROR("%s", refusal.c_str());
    localizer_.reset();
    refusal_ = refusal;
    return;
  }
  if (localizer_)
    return;
  if (params_.start_keyframe >= static_cast<int>(map_->size()))
    NODELET_WARN("~start_keyframe = %d is beyond map %s's %zu keyframes: the start is unknown (a global search)",
                 params_.start_keyframe, map_path_.c_str(), map_->size());
  try
  {
    if (drive_localized_)
    {
      // Refused in the middle of the drive: the robot is somewhere along the route, maybe far from
      // where it was when the refusal began. Not at the route start: unknown, a global search. A later
      // new drive (time going back) starts at start_keyframe again.
      LocalizerParams unknown_start = effectiveParams(params_);
      unknown_start.start_keyframe = -1;
      localizer_.reset(new Localizer(map_, unknown_start));
      localizer_->setParams(effectiveParams(params_));
      resumed_mid_drive_ = true;
    }
    else
    {
      localizer_.reset(new Localizer(map_, effectiveParams(params_)));
    }
    localizer_->measureMapStatisticsNow();  // on load, not on the first frame a check needs them
    if (!refusal_.empty())
      NODELET_INFO("Preprocessing parameters match map %s again; localizing%s", map_path_.c_str(),
                   drive_localized_ ? " from an unknown place (a global search), since the refusal began mid-drive" :
                                      "");
    refusal_.clear();
  }
  catch (const std::exception& e)
  {
    refusal_ = std::string("cannot localize against map ") + map_path_ + ": " + e.what();
    NODELET_ERROR("%s", refusal_.c_str());
  }
}

void LocalizerNodelet::paramsCb(const std_msgs::StringConstPtr& msg)
{
  std::string error;
  const std::shared_ptr<const PreprocessingParams> params = parseAnnouncedParameters(msg->data, &error);
  if (!params)
  {
    NODELET_ERROR("%s", error.c_str());
    return;
  }
  announced_ = params;
  useMapIfAccepted();
}

void LocalizerNodelet::imageCb(const sensor_msgs::ImageConstPtr& msg)
{
  // How long this callback takes, parameter changes included: frames that come meanwhile wait in an input
  // queue of 1, so all but the newest are lost, and the next frame shows a gap (FrameGapCounts::whileBusy).
  struct BusyClock
  {
    double* busy_s;
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now();
    ~BusyClock() { *busy_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); }
  };
  const double busy_before_s = busy_s_;
  const bool changed_before = changed_last_;
  const BusyClock busy{ &busy_s_ };
  bool changed = false;
  LocalizerParams requested;
  {
    std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
    if (params_changed_)
    {
      requested = requested_params_;
      params_changed_ = false;
      changed = true;
    }
  }
  changed_last_ = changed;
  if (changed)
  {
    params_ = requested;
    if (localizer_)
    {
      try
      {
        localizer_->setParams(effectiveParams(params_));  // between frames; keeps the current match
        localizer_->measureMapStatisticsNow();
      }
      catch (const std::exception& e)
      {
        NODELET_ERROR("Localizer rejected the new parameters: %s; keeping the previous ones", e.what());
      }
    }
  }

  if (!localizer_)  // (no frame comes without a map: the images are subscribed from the first map on)
  {
    dropFrame(kRefusedMap, refusal_);
    return;
  }
  if (!announced_ && !unchecked_warned_)
  {
    NODELET_WARN("No preprocessing parameters announced on %s: cannot check that map %s matches its input",
                 params_sub_.getTopic().c_str(), map_path_.c_str());
    unchecked_warned_ = true;
  }
  char sentence[512];
  if (msg->encoding != sensor_msgs::image_encodings::MONO8 && msg->encoding != sensor_msgs::image_encodings::TYPE_8UC1)
  {
    std::snprintf(sentence, sizeof(sentence),
                  "a %ux%u '%s' frame: the localizer takes the preprocessor's mono8 output (is %s remapped to a "
                  "camera topic?)",
                  msg->width, msg->height, msg->encoding.c_str(), image_sub_.getTopic().c_str());
    dropFrame(kEncoding, sentence);
    return;
  }
  if (static_cast<int>(msg->width) != map_->width() || static_cast<int>(msg->height) != map_->height() ||
      msg->step < msg->width || msg->data.size() < static_cast<size_t>(msg->step) * msg->height)
  {
    std::snprintf(sentence, sizeof(sentence),
                  "a %ux%u '%s' frame (step %u, %zu bytes): map %s holds %dx%d mono8 keyframes", msg->width,
                  msg->height, msg->encoding.c_str(), msg->step, msg->data.size(), map_path_.c_str(), map_->width(),
                  map_->height());
    dropFrame(kSize, sentence);
    return;
  }
  if (resumed_mid_drive_ && !last_stamp_.isZero() && msg->header.stamp < last_stamp_)
  {
    // The first frame since the restart is from before the last one: another drive, from the start.
    NODELET_WARN("Time went backwards (%.3f s -> %.3f s; a looping bag?): restarted the localization",
                 last_stamp_.toSec(), msg->header.stamp.toSec());
    ++resets_;
    try
    {
      localizer_.reset(new Localizer(map_, effectiveParams(params_)));
    }
    catch (const std::exception& e)
    {
      dropFrame(kFailure, std::string("the localizer failed to start over: ") + e.what());
      return;
    }
  }
  resumed_mid_drive_ = false;
  const cv_bridge::CvImageConstPtr input = cv_bridge::toCvShare(msg);
  const auto start = std::chrono::steady_clock::now();
  LocalizationResult result;
  try
  {
    // The stamp tells the core when time went back (it starts over) and when frames were missed.
    const RobotMotion motion =
        motion_sub_ ? standstill_.sinceLastFrame(msg->header.stamp.toSec()) : RobotMotion::kUnknown;
    result = localizer_->process(input->image, static_cast<int64_t>(msg->header.stamp.toNSec()), motion);
  }
  catch (const std::exception& e)
  {
    dropFrame(kFailure, std::string("the localizer failed on a frame: ") + e.what());
    return;
  }
  const double elapsed_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (result.time_went_back)
  {
    NODELET_WARN("Time went backwards (%.3f s -> %.3f s; a looping bag?): restarted the localization",
                 last_stamp_.toSec(), msg->header.stamp.toSec());
    ++resets_;
  }
  if (result.missed_frames > 0)
  {
    const double gap = (msg->header.stamp - last_stamp_).toSec();
    const bool while_busy = FrameGapCounts::whileBusy(busy_before_s, gap, result.missed_frames);
    if (while_busy)
      NODELET_WARN_THROTTLE(5.0, "The localizer spent %.3f s on the frame before this one%s: the frames of the "
                                 "%.3f s gap that follows came meanwhile and were replaced in its input queue of 1",
                            busy_before_s,
                            changed_before ? " (it applied a parameter change: the map's tables measured again)" : "",
                            gap);
    if (result.gap == FrameGap::kSearchedAgain)
      NODELET_WARN("A gap of %.3f s in the image stamps (%.3f s -> %.3f s), longer than the sequence window: "
                   "searching the whole map again",
                   gap, last_stamp_.toSec(), msg->header.stamp.toSec());
    else
      NODELET_WARN_THROTTLE(5.0, "A gap of %.3f s in the image stamps (%.3f s -> %.3f s): about %d frames missed; %s",
                            gap, last_stamp_.toSec(), msg->header.stamp.toSec(), result.missed_frames,
                            result.gap == FrameGap::kFilledIn    ? "the localization goes on through them" :
                            result.gap == FrameGap::kNotFilledIn ? "not filled in (fill_frame_gaps is off)" :
                                                                   "the view after it is the one before it: the "
                                                                   "robot stood still, nothing filled in");
    gaps_.add(result, while_busy);
  }
  last_stamp_ = msg->header.stamp;

  const LocalizationPtr out = boost::make_shared<Localization>();
  out->header = msg->header;
  out->status = toMsgStatus(result.status);
  out->keyframe = result.keyframe;
  if (result.keyframe_stamp_ns > 0)
    out->keyframe_stamp.fromNSec(static_cast<uint64_t>(result.keyframe_stamp_ns));
  out->confidence = static_cast<float>(result.confidence);
  out->homing_angle = static_cast<float>(result.homing_angle_rad);
  out->shift = static_cast<float>(result.shift_px);
  out->query_informative = result.query_informative;
  localization_pub_.publish(out);

  if (debug_pub_.getNumSubscribers() > 0)
    publishDebugImage(msg->header, result);

  last_result_ = result;
  drive_localized_ = true;
  last_frame_received_ = ros::Time::now();
  dropped_.used();
  ++frames_;
  ++frames_in_period_;
  time_sum_ms_ += elapsed_ms;
  time_max_ms_ = std::max(time_max_ms_, elapsed_ms);
  last_time_ms_ = elapsed_ms;
  if (input_buffer_pub_)
  {
    // Equal to the address of the buffer the preprocessor filled when the hand-over in one manager
    // copies nothing.
    char text[96];
    std::snprintf(text, sizeof(text), "%p @ %u.%09u", static_cast<const void*>(input->image.data),
                  msg->header.stamp.sec, msg->header.stamp.nsec);
    std_msgs::String report;
    report.data = text;
    input_buffer_pub_.publish(report);
  }
  rate_status_->tick();
}

void LocalizerNodelet::publishDebugImage(const std_msgs::Header& header, const LocalizationResult& result)
{
  const int keyframes = static_cast<int>(map_->size());
  const int width = std::min(keyframes, 2 * std::max(params_.search_radius, 1) + 1);
  const int center = result.keyframe >= 0 ? result.keyframe : 0;
  DebugImageContent content;
  content.first_keyframe = std::max(0, std::min(center - width / 2, keyframes - width));
  content.keyframes = width;
  content.path = localizer_->lastPath();
  content.match_keyframe = result.keyframe;
  content.status = toString(result.status);
  content.confidence = result.confidence;
  content.cost_clamp = params_.contrast_clamp;
  content.cell_px = debug_image_scale_;
  // Drawn straight into the message's buffer (a viewer's size: debug_image.h).
  const sensor_msgs::ImagePtr out = boost::make_shared<sensor_msgs::Image>();
  try
  {
    const DebugImageLayout layout = debugImageLayout(content, localizer_->costs().capacity());
    out->header = header;
    out->encoding = sensor_msgs::image_encodings::BGR8;
    out->width = static_cast<uint32_t>(layout.size.width);
    out->height = static_cast<uint32_t>(layout.size.height);
    out->step = out->width * 3;
    out->data.resize(static_cast<size_t>(out->step) * out->height);
    cv::Mat wrapped(layout.size, CV_8UC3, &out->data[0], out->step);
    renderDebugImage(localizer_->costs(), content, wrapped);
    if (wrapped.data != &out->data[0])
      return;  // not drawn in place (cannot happen with the layout's size)
  }
  catch (const std::exception& e)
  {
    NODELET_ERROR_THROTTLE(5.0, "Cannot render the debug image: %s", e.what());
    return;
  }
  debug_pub_.publish(out);
}

void LocalizerNodelet::dropFrame(Drop kind, const std::string& sentence)
{
  if (!dropped_.drop(kind, sentence))
    return;
  if (kind == kRefusedMap)
    NODELET_ERROR("Dropping frames: %s", sentence.c_str());
  else
    NODELET_ERROR("Dropping %s", sentence.c_str());
}

void LocalizerNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  if (!transport_error_.empty())
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                 "not subscribed to " + image_topic_ + ": " + transport_error_);
  else if (!map_)
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR,
                 map_error_ + "; not listening to " + image_topic_ + " until a map is loaded");
  else if (!localizer_)
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, refusal_);
  else if (dropped_.newestDropped())
    stat.summary(diagnostic_msgs::DiagnosticStatus::ERROR, "dropping " + dropped_.lastReason());
  else if (frames_ == 0)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "waiting for images on " + image_topic_);
  else if (last_result_.status == LocalizationStatus::kLost)
    stat.summary(diagnostic_msgs::DiagnosticStatus::WARN, "lost: searching the whole map");
  else
    stat.summary(diagnostic_msgs::DiagnosticStatus::OK, toString(last_result_.status));

  stat.add("map", map_ ? map_path_ : std::string("(none)"));
  stat.add("keyframes", map_ ? map_->size() : 0);
  stat.add("frames processed", frames_);
  dropped_.addTo(stat, "frame");
  stat.add("resets (time went backwards)", resets_);
  stat.add("gaps in the image stamps", gaps_.gaps);
  stat.add("frames missed in gaps that did not restart the search", gaps_.missed_frames);
  stat.add("gaps that restarted the search", gaps_.searched_again);
  stat.add("of the frames missed, while the localizer was busy", gaps_.missed_while_busy);
  stat.add("status", toString(last_result_.status));
  stat.add("keyframe", last_result_.keyframe);
  stat.add("confidence", last_result_.confidence);
  stat.add("homing angle (rad)", last_result_.homing_angle_rad);
  stat.addf("processing time last (ms)", "%.3f", last_time_ms_);
  // Mean and max over the frames since the previous report; none when no frame came since (a drive ended).
  stat.add("frames since the last report", frames_in_period_);
  if (frames_in_period_ > 0)
  {
    stat.addf("processing time mean since the last report (ms)", "%.3f", time_sum_ms_ / frames_in_period_);
    stat.addf("processing time max since the last report (ms)", "%.3f", time_max_ms_);
  }
  else
  {
    stat.add("processing time mean since the last report (ms)", "none");
    stat.add("processing time max since the last report (ms)", "none");
  }
  frames_in_period_ = 0;
  time_sum_ms_ = 0.0;
  time_max_ms_ = 0.0;
}

}  // namespace along_route_localization

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(along_route_localization::LocalizerNodelet, nodelet::Nodelet)
