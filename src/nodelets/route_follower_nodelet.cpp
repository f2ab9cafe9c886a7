// Repeat, closed loop: drives the taught route from each localization with the core RouteFollower
// (route_follower.h) and the motion the map recorded with each keyframe.
//
// Subscribes: localization (along_route_localization/Localization, from the localizer)
// Publishes:  cmd_vel (geometry_msgs/Twist) at ~control_rate while following, and while the command
//             ramps down to zero after a stop (then one zero command, then nothing: a teleop can take over)
//             /diagnostics (state, why it drives as it does or why it stopped, the command and its target)
// Services:   ~start, ~pause, ~stop (std_srvs/Trigger); ~start reads ~map again while none was loaded
//             (a map taught after the follower was started)
// Parameters: ~map (the map file written by teach.launch, with its taught motion), ~autostart (false),
//             ~control_rate (20 Hz); cfg/RouteFollower.cfg (dynamic)
//
// Times are ROS time (sim time with /clock): a localization counts when it is received, so the watchdog
// sees a localizer that stopped, whatever stamps its camera gave.
#include <cctype>
#include <cmath>
#include <map>
#include <functional>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include <boost/thread/recursive_mutex.hpp>
#include <diagnostic_updater/diagnostic_updater.h>
#include <dynamic_reconfigure/server.h>
#include <geometry_msgs/Twist.h>
#include <nodelet/nodelet.h>
#include <std_srvs/Trigger.h>

#include "along_route_localization/Localization.h"
#include "along_route_localization/RouteFollowerConfig.h"
#include "along_route_localization/parameters.h"
#include "along_route_localization/route_follower.h"
#include "glue/diagnostics.h"
#include "glue/map_io.h"
#include "glue/private_parameters.h"
#include "glue/reconfigure.h"

namespace along_route_localization
{

class RouteFollowerNodelet : public nodelet::Nodelet
{
private:
  void onInit() override;
  void localizationCb(const LocalizationConstPtr& msg);
  void controlCb(const ros::TimerEvent& event);
  void configCb(RouteFollowerConfig& config, uint32_t level);
  bool startCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool pauseCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool stopCb(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  /// A service's answer: `action` on the follower, or `without_map` and why there is none; logged.
  bool serve(const char* name, const char* without_map, std_srvs::Trigger::Response& res,
             const std::function<bool(std::string*)>& action);
  void loadMap(const std::string& path);
  void applyParams();
  void diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat);

  // Static parameters, read in onInit.
  std::string map_path_;
  double control_rate_hz_ = 20.0;

  ros::Subscriber localization_sub_;
  ros::Publisher cmd_vel_pub_;
  ros::ServiceServer start_srv_, pause_srv_, stop_srv_;
  ros::Timer control_timer_;
  std::shared_ptr<diagnostic_updater::Updater> updater_;
  ros::WallTimer diagnostics_timer_;

  // Written by configCb, copied by controlCb; guarded by config_mutex_ (also the server's mutex).
  boost::recursive_mutex config_mutex_;
  std::shared_ptr<dynamic_reconfigure::Server<RouteFollowerConfig>> reconfigure_server_;
  RouteFollowerParams requested_params_;
  bool params_changed_ = false;
  RouteFollowerConfig last_valid_config_ = RouteFollowerConfig::__getDefault__();

  // Used only from the nodelet's single-threaded callback queue (localizations, the control timer, the
  // services and the diagnostics timer), so nothing here needs a lock.
  std::unique_ptr<RouteFollower> follower_;  // null while the map gives no taught motion
  std::string map_error_;                    // why follower_ is null
  FollowerCommand last_command_;
  uint64_t localizations_ = 0, commands_published_ = 0;
};

void RouteFollowerNodelet::onInit()
{
  ros::NodeHandle& nh = getNodeHandle();
  ros::NodeHandle& private_nh = getPrivateNodeHandle();

  std::set<std::string> read = configParameterNames<RouteFollowerConfig>();
  const std::set<std::string>& own = nodeletSettingNames(ParameterGroup::kRouteFollower);
  read.insert(own.begin(), own.end());
  for (const std::string& name : unreadParameters(private_nh, read))
    NODELET_WARN("%s", unreadSentence(name, "route follower", read).c_str());
  std::string problem;
  map_path_ = readStringParameter(private_nh, "map", std::string(), &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  const bool autostart = readBoolParameter(private_nh, "autostart", false, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  control_rate_hz_ = readDoubleParameter(private_nh, "control_rate", control_rate_hz_, &problem);
  if (!problem.empty())
    NODELET_ERROR("%s", problem.c_str());
  if (!(control_rate_hz_ >= 1.0 && control_rate_hz_ <= 1000.0))
  {
    NODELET_ERROR("~control_rate must be 1 to 1000 Hz (%g); using 20", control_rate_hz_);
    control_rate_hz_ = 20.0;
  }

  for (const std::string& sentence : mistypedParameters<RouteFollowerConfig>(private_nh))
    NODELET_WARN("%s", sentence.c_str());
  reconfigure_server_ = std::make_shared<dynamic_reconfigure::Server<RouteFollowerConfig>>(config_mutex_, private_nh);
  reconfigure_server_->setCallback([this](RouteFollowerConfig& config, uint32_t level) { configCb(config, level); });

  loadMap(map_path_);
  if (follower_ && autostart)
  {
    std::string message;
    follower_->start(ros::Time::now().toSec(), &message);
    NODELET_INFO("~autostart: %s", message.c_str());
  }

  updater_ = std::make_shared<diagnostic_updater::Updater>(nh, private_nh, getName());
  updater_->setHardwareID("none");
  updater_->add("following", this, &RouteFollowerNodelet::diagnose);
  diagnostics_timer_ = startDiagnosticsTimer(nh, updater_);

  cmd_vel_pub_ = nh.advertise<geometry_msgs::Twist>("cmd_vel", 10);
  start_srv_ = private_nh.advertiseService("start", &RouteFollowerNodelet::startCb, this);
  pause_srv_ = private_nh.advertiseService("pause", &RouteFollowerNodelet::pauseCb, this);
  stop_srv_ = private_nh.advertiseService("stop", &RouteFollowerNodelet::stopCb, this);
  localization_sub_ = nh.subscribe("localization", 10, &RouteFollowerNodelet::localizationCb, this);
  control_timer_ = nh.createTimer(ros::Duration(1.0 / control_rate_hz_), &RouteFollowerNodelet::controlCb, this);
  NODELET_INFO("Following %s from %s, commands on %s at %g Hz (%s)",
               map_path_.empty() ? "(no map)" : map_path_.c_str(), nh.resolveName("localization").c_str(),
               nh.resolveName("cmd_vel").c_str(), control_rate_hz_,
               !follower_ ? "will not drive" : (follower_->state() == RouteFollower::State::kFollowing ?
                                                    "started" : "call ~start to drive"));
}

void RouteFollowerNodelet::loadMap(const std::string& path)
{
  if (path.empty())
  {
    map_error_ = "no ~map parameter: set it to the map file written by teach.launch";
    NODELET_ERROR("%s; the follower will not drive", map_error_.c_str());
    return;
  }
  map_error_.clear();
  try
  {
    requireAbsoluteMapPath(path);
    std::map<int, TaughtMotion> recorded;
    const RouteMap map = readMap(path, &recorded);
    std::vector<TaughtMotion> motion = completeTaughtMotion(recorded, map.size());
    if (motion.empty())
      throw MapError("map file '" + path + "' holds no taught motion (topic '" + kMapMotionTopic +
                     "'): it was taught without the velocity topic; teach again with teach.launch motion:=<the "
                     "robot's cmd_vel or odometry>");
    RouteFollowerParams params;
    {
      std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
      params = requested_params_;
      params_changed_ = false;
    }
    std::vector<int64_t> stamps_ns(map.size());
    for (size_t k = 0; k < map.size(); ++k)
      stamps_ns[k] = map.stampNs(k);
    std::unique_ptr<RouteFollower> follower(new RouteFollower(std::move(motion), params));
    follower->setKeyframeStamps(std::move(stamps_ns));
    follower_ = std::move(follower);
    NODELET_INFO("Map %s: %zu keyframes with taught motion", path.c_str(), follower_->keyframes());
  }
  catch (const std::exception& e)
  {
    map_error_ = e.what();
    NODELET_ERROR("The follower will not drive: %s", map_error_.c_str());
  }
}

void RouteFollowerNodelet::configCb(RouteFollowerConfig& config, uint32_t /*level*/)
{
  // Corrections, so the panel shows the values in use: each value into its working range (the parameter
  // table's), then the combination.
  std::vector<std::string> corrections = correctToTable(config, last_valid_config_);
  if (config.stop_after_frames < config.slow_after_frames)
  {
    corrections.push_back("stop_after_frames " + std::to_string(config.stop_after_frames) +
                          " is below slow_after_frames " + std::to_string(config.slow_after_frames) + "; using " +
                          std::to_string(config.slow_after_frames));
    config.stop_after_frames = config.slow_after_frames;
  }
  const RouteFollowerParams params = toParams(config);
  const ConfigReview review = reviewConfig(config, last_valid_config_, std::move(corrections), params.validate());
  logConfigReview(review, getName(), "route follower parameters");
  if (!review.rejected.empty())
    return;
  requested_params_ = params;
  params_changed_ = true;
}

void RouteFollowerNodelet::applyParams()
{
  RouteFollowerParams params;
  {
    std::lock_guard<boost::recursive_mutex> lock(config_mutex_);
    if (!params_changed_)
      return;
    params = requested_params_;
    params_changed_ = false;
  }
  if (follower_)
    follower_->setParams(params);  // validated in configCb
}

void RouteFollowerNodelet::localizationCb(const LocalizationConstPtr& msg)
{
  ++localizations_;
  if (!follower_)
    return;
  FollowerInput input;
  switch (msg->status)
  {
    case Localization::STATUS_INITIALIZING:
      input.status = LocalizationStatus::kInitializing;
      break;
    case Localization::STATUS_TRACKING:
      input.status = LocalizationStatus::kTracking;
      break;
    case Localization::STATUS_END_OF_ROUTE:
      input.status = LocalizationStatus::kEndOfRoute;
      break;
    case Localization::STATUS_LOST:
      input.status = LocalizationStatus::kLost;
      break;
    default:
      NODELET_ERROR_THROTTLE(5.0, "Localization with unknown status %u: taken as lost", msg->status);
      input.status = LocalizationStatus::kLost;
  }
  input.keyframe = msg->keyframe;
  input.confidence = msg->confidence;
  input.homing_angle_rad = msg->homing_angle;
  input.informative = msg->query_informative;
  input.keyframe_stamp_ns = static_cast<int64_t>(msg->keyframe_stamp.toNSec());
  const ros::Time now = ros::Time::now();
  if (now.isZero())
  {
    // use_sim_time before the first /clock: a localization taken at time 0 made the first command's watchdog
    // say "no localization for 1000.05 s" (the simulator's clock starts at 1000 s).
    NODELET_WARN_THROTTLE(5.0, "ROS time is 0 (use_sim_time, and no /clock yet): localizations are taken once "
                               "the clock runs");
    return;
  }
  const RouteFollower::State before = follower_->state();
  follower_->localization(input, now.toSec());
  if (before != follower_->state() && follower_->state() == RouteFollower::State::kFinished)
    NODELET_INFO("End of the route at keyframe %d of %zu: stopping", msg->keyframe, follower_->keyframes());
}

namespace
{

/// The text with each number in it (digits, with a point inside) replaced by '#'.
std::string withoutNumbers(const std::string& text)
{
  std::string out;
  for (size_t i = 0; i < text.size(); ++i)
  {
    const bool digit = std::isdigit(static_cast<unsigned char>(text[i])) != 0;
    const bool inner_point = text[i] == '.' && i > 0 && i + 1 < text.size() &&
                             std::isdigit(static_cast<unsigned char>(text[i - 1])) &&
                             std::isdigit(static_cast<unsigned char>(text[i + 1]));
    if (!digit && !inner_point)
      out += text[i];
    else if (out.empty() || out.back() != '#')
      out += '#';
  }
  return out;
}

}  // namespace

void RouteFollowerNodelet::controlCb(const ros::TimerEvent& /*event*/)
{
  if (!follower_ || ros::Time::now().isZero())  // no clock yet (use_sim_time): nothing to time a command by
    return;
  applyParams();
  const bool was_driving = follower_->driving();
  const std::string reason_before = follower_->reason();
  // A gap of more than two control periods (a clock that jumped ahead, a stalled manager) ramps as two.
  last_command_ = follower_->command(ros::Time::now().toSec(), 2.0 / control_rate_hz_);
  // Said when the reason changes, not when a number in it does (the seconds without a localization, the
  // metres crept: once per control tick, 20 lines a second into the log).
  if (withoutNumbers(follower_->reason()) != withoutNumbers(reason_before) &&
      follower_->state() == RouteFollower::State::kFollowing)
  {
    if (follower_->safetyScale() < 1.0)
      NODELET_WARN("%s", follower_->reason().c_str());
    else
      NODELET_INFO("%s", follower_->reason().c_str());
  }
  if (!was_driving && !follower_->driving())
    return;
  geometry_msgs::TwistPtr twist = boost::make_shared<geometry_msgs::Twist>();
  twist->linear.x = last_command_.linear_mps;
  twist->angular.z = last_command_.angular_rps;
  cmd_vel_pub_.publish(twist);
  ++commands_published_;
}

bool RouteFollowerNodelet::startCb(std_srvs::Trigger::Request& /*req*/, std_srvs::Trigger::Response& res)
{
  if (!follower_ && !map_path_.empty())
    loadMap(map_path_);
  return serve("start", "cannot drive: ", res,
               [this](std::string* message) { return follower_->start(ros::Time::now().toSec(), message); });
}

bool RouteFollowerNodelet::pauseCb(std_srvs::Trigger::Request& /*req*/, std_srvs::Trigger::Response& res)
{
  return serve("pause", "not driving: ", res, [this](std::string* message) { return follower_->pause(message); });
}

bool RouteFollowerNodelet::stopCb(std_srvs::Trigger::Request& /*req*/, std_srvs::Trigger::Response& res)
{
  return serve("stop", "not driving: ", res, [this](std::string* message) { return follower_->stop(message); });
}

bool RouteFollowerNodelet::serve(const char* name, const char* without_map, std_srvs::Trigger::Response& res,
                                 const std::function<bool(std::string*)>& action)
{
  if (!follower_)
  {
    res.success = false;
    res.message = without_map + map_error_;
  }
  else
  {
    res.success = action(&res.message);
  }
  NODELET_INFO("~%s: %s", name, res.message.c_str());
  return true;
}

void RouteFollowerNodelet::diagnose(diagnostic_updater::DiagnosticStatusWrapper& stat)
{
  using diagnostic_msgs::DiagnosticStatus;
  stat.add("map", map_path_.empty() ? std::string("(none)") : map_path_);
  stat.add("localizations received", localizations_);
  stat.add("commands published", commands_published_);
  if (!follower_)
  {
    stat.summary(DiagnosticStatus::ERROR, "will not drive: " + map_error_);
    stat.add("state", "no map");
    return;
  }
  const std::string state = toString(follower_->state());
  const std::string& reason = follower_->reason();
  // A stop takes time at max_linear_decel: until the command is zero, say that the robot still moves.
  const std::string summary = follower_->braking() ? "braking to a stop: " + reason : reason;
  if (follower_->state() == RouteFollower::State::kFollowing && follower_->safetyScale() < 1.0)
    stat.summary(DiagnosticStatus::WARN, summary);
  else
    stat.summary(DiagnosticStatus::OK, summary);
  stat.add("state", state);
  stat.add("reason", reason);
  stat.add("keyframes", follower_->keyframes());
  stat.add("keyframe", follower_->lastKeyframe());
  stat.addf("linear command (m/s)", "%.3f", last_command_.linear_mps);
  stat.addf("angular command (rad/s)", "%.3f", last_command_.angular_rps);
  stat.addf("linear target (m/s)", "%.3f", follower_->target().linear_mps);
  stat.addf("angular target (rad/s)", "%.3f", follower_->target().angular_rps);
  stat.addf("safety scale", "%.2f", follower_->safetyScale());
  stat.add("low-confidence localizations in a row", follower_->lowConfidenceFrames());
  stat.addf("filtered homing angle (rad)", "%.4f", follower_->filteredHomingAngle());
}

}  // namespace along_route_localization

#include <pluginlib/class_list_macros.hpp>
PLUGINLIB_EXPORT_CLASS(along_route_localization::RouteFollowerNodelet, nodelet::Nodelet)
