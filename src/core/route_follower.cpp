#include "along_route_localization/route_follower.h"

#include "along_route_localization/parameters.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace along_route_localization
{
namespace
{

double approach(double from, double to, double max_step)
{
  if (to > from + max_step)
    return from + max_step;
  if (to < from - max_step)
    return from - max_step;
  return to;
}

/// The forward speed from `from` towards `to` after dt: |v| grows at most `accel`, falls (towards 0) at most
/// `decel`; a change of direction brakes to 0 first, then speeds up the other way with the time left.
double rampSpeed(double from, double to, double accel, double decel, double dt)
{
  const bool reverses = from * to < 0.0;
  const bool slowing = reverses || std::fabs(to) < std::fabs(from);
  if (!slowing)
    return approach(from, to, accel * dt);
  const double brake_to = reverses ? 0.0 : to;
  const double braking_s = std::fabs(from - brake_to) / decel;
  if (dt <= braking_s || !reverses)
    return approach(from, brake_to, decel * dt);
  return approach(0.0, to, accel * (dt - braking_s));
}

std::string formatted(const char* format, double a, double b = 0.0, double c = 0.0)
{
  char text[256];
  std::snprintf(text, sizeof(text), format, a, b, c);
  return text;
}

}  // namespace

std::vector<TaughtMotion> completeTaughtMotion(const std::map<int, TaughtMotion>& recorded, size_t keyframes)
{
  std::vector<TaughtMotion> motion;
  auto valid_end = recorded.lower_bound(static_cast<int>(std::min<size_t>(keyframes, 1u << 30)));
  auto valid_begin = recorded.lower_bound(0);
  if (keyframes == 0 || valid_begin == valid_end)
    return motion;
  motion.reserve(keyframes);
  for (size_t k = 0; k < keyframes; ++k)
  {
    const int index = static_cast<int>(k);
    auto after = recorded.lower_bound(index);  // first record at or after k
    if (after != valid_end && after->first == index)
    {
      motion.push_back(after->second);
      continue;
    }
    if (after == valid_begin)
    {
      motion.push_back(after->second);
      continue;
    }
    auto before = std::prev(after);
    if (after == valid_end || index - before->first <= after->first - index)
      motion.push_back(before->second);
    else
      motion.push_back(after->second);
  }
  return motion;
}

std::string RouteFollowerParams::validate() const
{
  // The working range of each parameter is the table's (parameters.cpp); the rest is the one combination.
  ParameterSet set;
  set.follower = *this;
  const std::string out_of_range = checkRanges(ParameterGroup::kRouteFollower, set);
  if (!out_of_range.empty())
    return out_of_range;
  std::ostringstream e;
  if (stop_after_frames < slow_after_frames)
    e << "stop_after_frames must be >= slow_after_frames (" << slow_after_frames << "), got " << stop_after_frames;
  return e.str();
}

std::string toString(RouteFollower::State state)
{
  switch (state)
  {
    case RouteFollower::State::kIdle:
      return "idle";
    case RouteFollower::State::kFollowing:
      return "following";
    case RouteFollower::State::kPaused:
      return "paused";
    case RouteFollower::State::kStopped:
      return "stopped";
    case RouteFollower::State::kFinished:
      return "finished";
  }
  return "unknown";
}

RouteFollower::RouteFollower(std::vector<TaughtMotion> motion, const RouteFollowerParams& params)
  : motion_(std::move(motion))
{
  if (motion_.empty())
    throw std::invalid_argument("the map holds no taught motion: the follower cannot drive it (teach again with "
                                "the velocity topic recorded)");
  has_distances_ = std::any_of(motion_.begin(), motion_.end(), [](const TaughtMotion& m) { return m.distance_m > 0.0; });
  setParams(params);
}

void RouteFollower::setParams(const RouteFollowerParams& params)
{
  const std::string invalid = params.validate();
  if (!invalid.empty())
    throw std::invalid_argument(invalid);
  params_ = params;
}

void RouteFollower::setKeyframeStamps(std::vector<int64_t> stamps_ns)
{
  if (stamps_ns.size() != motion_.size())
    throw std::invalid_argument("keyframe stamps: " + std::to_string(stamps_ns.size()) + " for " +
                                std::to_string(motion_.size()) + " keyframes of taught motion");
  stamps_ns_ = std::move(stamps_ns);
}

bool RouteFollower::driving() const
{
  return state_ == State::kFollowing || command_.linear_mps != 0.0 || command_.angular_rps != 0.0;
}

bool RouteFollower::braking() const
{
  const bool at_rest_target = target_.linear_mps == 0.0 && target_.angular_rps == 0.0;
  return at_rest_target && (command_.linear_mps != 0.0 || command_.angular_rps != 0.0);
}

bool RouteFollower::start(double now_s, std::string* message)
{
  if (state_ == State::kFollowing)
  {
    *message = "already following";
    return false;
  }
  const State before = state_;
  if (!driving())
  {
    // The ramp starts now, not at the last command (which may be long ago).
    command_s_ = now_s;
    have_command_time_ = true;
  }
  low_frames_ = 0;
  homing_filtered_rad_ = 0.0;
  confident_since_start_ = false;
  crept_m_ = 0.0;
  creeping_ = creep_begun_ = false;
  state_ = State::kFollowing;
  *message = before == State::kPaused ? "resumed following" : "started following";
  return true;
}

bool RouteFollower::pause(std::string* message)
{
  if (state_ != State::kFollowing)
  {
    *message = "not following (" + toString(state_) + ")";
    return false;
  }
  state_ = State::kPaused;
  *message = "paused: the robot slows to a stop; start resumes";
  return true;
}

bool RouteFollower::stop(std::string* message)
{
  if (state_ == State::kStopped || state_ == State::kIdle)
  {
    *message = "not following (" + toString(state_) + ")";
    return false;
  }
  state_ = State::kStopped;
  *message = "stopped: the robot slows to a stop; start follows again";
  return true;
}

void RouteFollower::localization(const FollowerInput& input, double now_s)
{
  // A localization on the route of another map (its keyframe's teach stamp and this map's both known, and
  // different) says nothing about where the robot is on this one: until one on this map comes, lost and
  // initializing ones included, the robot stops (computeTarget), creeps on nothing, and no end of route
  // finishes it; the track's bookkeeping starts afresh as after a loss.
  const bool tracked =
      input.status == LocalizationStatus::kTracking || input.status == LocalizationStatus::kEndOfRoute;
  if (tracked && input.keyframe >= 0 && input.keyframe < static_cast<int>(motion_.size()))
  {
    const int64_t own = stamps_ns_.empty() ? 0 : stamps_ns_[static_cast<size_t>(input.keyframe)];
    const bool foreign = input.keyframe_stamp_ns != 0 && own != 0 && input.keyframe_stamp_ns != own;
    foreign_stamp_ns_ = foreign ? input.keyframe_stamp_ns : 0;
    if (foreign)
      foreign_keyframe_ = input.keyframe;
  }
  const bool on_route = tracked && foreign_stamp_ns_ == 0;
  if (!on_route)
  {
    // Lost or initializing: the homing angle and the confidence count start afresh with the track.
    low_frames_ = 0;
    homing_filtered_rad_ = 0.0;
    confident_since_start_ = false;
  }
  else
  {
    const bool was_on_route = have_input_ && last_on_route_;
    if (std::isfinite(input.homing_angle_rad))
    {
      const double dt = std::max(0.0, now_s - last_input_s_);
      if (!was_on_route)
        homing_filtered_rad_ = input.homing_angle_rad;
      else
      {
        const double tau = params_.homing_time_constant_s;
        const double alpha = tau > 0.0 ? dt / (tau + dt) : 1.0;
        homing_filtered_rad_ += alpha * (input.homing_angle_rad - homing_filtered_rad_);
      }
    }
    // NaN counts as low confidence.
    if (input.confidence >= params_.min_confidence)
    {
      low_frames_ = 0;
      confident_since_start_ = true;
      crept_m_ = 0.0;  // found again: a later stop may creep again
    }
    else
      ++low_frames_;
    last_on_route_keyframe_ = input.keyframe;
  }
  last_input_ = input;
  last_input_s_ = now_s;
  last_on_route_ = on_route;
  have_input_ = true;
  if (state_ == State::kFollowing && on_route && input.status == LocalizationStatus::kEndOfRoute)
    state_ = State::kFinished;
}

void RouteFollower::computeTarget(double now_s)
{
  creeping_ = false;
  target_ = FollowerCommand();
  scale_ = 0.0;
  switch (state_)
  {
    case State::kIdle:
      reason_ = "idle: call start";
      return;
    case State::kPaused:
      reason_ = "paused: call start to resume";
      return;
    case State::kStopped:
      reason_ = "stopped by the stop service: call start";
      return;
    case State::kFinished:
      reason_ = "finished: the end of the route (keyframe " + std::to_string(last_input_.keyframe) + " of " +
                std::to_string(motion_.size()) + ")";
      return;
    case State::kFollowing:
      break;
  }
  if (!have_input_)
  {
    reason_ = "stopped: waiting for the first localization";
    return;
  }
  const double silence_s = now_s - last_input_s_;
  if (silence_s < 0.0)
  {
    reason_ = "stopped: time went back since the last localization (a restarted clock?); waiting for the next one";
    return;
  }
  if (silence_s > params_.watchdog_timeout_s)
  {
    reason_ = formatted("stopped: no localization for %.2f s (watchdog_timeout %.2f s)", silence_s,
                        params_.watchdog_timeout_s);
    return;
  }
  if (foreign_stamp_ns_ != 0)
  {
    const size_t k = static_cast<size_t>(foreign_keyframe_);
    reason_ = formatted("stopped: keyframe %.0f was taught at %.3f s in the localizer's map, at %.3f s in the "
                        "follower's: they are different maps (load the same map in both)",
                        static_cast<double>(k), 1e-9 * static_cast<double>(foreign_stamp_ns_),
                        1e-9 * static_cast<double>(stamps_ns_[k]));
    return;
  }
  if (last_input_.status == LocalizationStatus::kLost)
  {
    creepOrStop("the localization is lost");
    return;
  }
  if (last_input_.status == LocalizationStatus::kInitializing)
  {
    reason_ = "stopped: the localization is initializing";
    return;
  }
  if (last_input_.keyframe < 0 || last_input_.keyframe >= static_cast<int>(motion_.size()))
  {
    reason_ = "stopped: keyframe " + std::to_string(last_input_.keyframe) + " is not among the map's " +
              std::to_string(motion_.size()) + " keyframes (localizing against another map?)";
    return;
  }
  if (!confident_since_start_)
  {
    // A standing robot brings the localizer no new views, so its confidence stays low: stopping here would
    // never start. Slow until the first confident answer; the localizer's loss detection stops it if none comes.
    scale_ = params_.slow_factor;
    reason_ = formatted("starting: slow until a localization with confidence >= %.2f", params_.min_confidence);
  }
  else if (low_frames_ >= params_.stop_after_frames)
  {
    creepOrStop(formatted("confidence below %.2f for %.0f localizations in a row", params_.min_confidence,
                          low_frames_));
    return;
  }
  else if (low_frames_ >= params_.slow_after_frames)
  {
    scale_ = params_.slow_factor;
    reason_ = formatted("slowing: confidence below %.2f for %.0f localizations in a row", params_.min_confidence,
                        low_frames_);
  }
  else
  {
    scale_ = 1.0;
    reason_ = "following";
  }
  const double homing_rps = std::max(-params_.max_homing_turn_rps,
                                     std::min(params_.max_homing_turn_rps, params_.homing_gain * homing_filtered_rad_));
  setTarget(motion_[static_cast<size_t>(last_input_.keyframe)], homing_rps);
  creep_begun_ = false;  // driving on the track again: a later creep starts from where it is then
}

void RouteFollower::setTarget(const TaughtMotion& taught, double homing_rps)
{
  target_.linear_mps = scale_ * params_.speed_factor * taught.linear_mps;
  target_.angular_rps = scale_ * (params_.speed_factor * taught.angular_rps + homing_rps);
}

size_t RouteFollower::creepKeyframe() const
{
  // Keyframes the teach took while standing (distance 0) are passed at once. A map without distances
  // (none recorded) reckons nothing: the creep stays at its anchor.
  size_t k = static_cast<size_t>(creep_anchor_);
  double left_m = crept_m_ - anchor_crept_m_;
  while (has_distances_ && k + 1 < motion_.size() && left_m >= motion_[k + 1].distance_m)
    left_m -= motion_[++k].distance_m;
  return k;
}

void RouteFollower::creepOrStop(const std::string& why)
{
  // The creep follows the taught motion on from the last keyframe the track held, reckoned by the distance
  // crept, without the homing term (the angle of an unconfident or lost match is not trusted): at slow_factor
  // it brings the localizer new views within a bounded distance, and the first confident answer ends it.
  if (!creep_begun_)
  {
    creep_anchor_ = last_on_route_keyframe_;
    anchor_crept_m_ = crept_m_;
  }
  const bool anchored = creep_anchor_ >= 0 && creep_anchor_ < static_cast<int>(motion_.size());
  const size_t k = anchored ? creepKeyframe() : 0;
  const bool can_creep = anchored && crept_m_ < params_.recovery_distance_m && k + 1 < motion_.size();
  if (!can_creep)
  {
    reason_ = "stopped: " + why;
    if (crept_m_ > 0.0)
      reason_ += formatted(" (crept %.2f m of recovery_distance %.2f m without a confident localization)", crept_m_,
                           params_.recovery_distance_m);
    return;
  }
  if (!last_input_.informative)
  {
    // A featureless view (covered, dark): moving brings no view to localize on, and whatever covers the
    // camera may stand in front of the robot. Wait, keeping the distance left for when the view comes back.
    creep_begun_ = true;  // the same creep goes on from the same anchor once the view is back
    reason_ = "stopped: " + why + "; the view is featureless: the creep waits for one with texture";
    return;
  }
  creeping_ = creep_begun_ = true;
  scale_ = params_.slow_factor;
  // The motion the teach recorded on the way from keyframe k to k + 1 (a keyframe's record is its motion
  // since the previous one): the teach robot was moving there, also when it stood at k.
  setTarget(motion_[k + 1], 0.0);
  reason_ = "creeping: " + why +
            formatted("; %.2f of recovery_distance %.2f m, to bring new views (reckoned keyframe %.0f)", crept_m_,
                      params_.recovery_distance_m, static_cast<double>(k));
}

FollowerCommand RouteFollower::command(double now_s, double max_step_s)
{
  computeTarget(now_s);
  if (have_command_time_ && now_s < command_s_)
    command_s_ = now_s;  // time went back: no change in this call, ramps go on from here
  const double elapsed = have_command_time_ ? std::max(0.0, now_s - command_s_) : 0.0;
  const double dt = std::min(elapsed, max_step_s);
  command_.linear_mps =
      rampSpeed(command_.linear_mps, target_.linear_mps, params_.max_linear_accel, params_.max_linear_decel, dt);
  command_.angular_rps = approach(command_.angular_rps, target_.angular_rps, params_.max_angular_accel * dt);
  if (creeping_)
    crept_m_ += std::fabs(command_.linear_mps) * elapsed;  // the whole gap: a stalled robot may have driven on
  command_s_ = now_s;
  have_command_time_ = true;
  return command_;
}

}  // namespace along_route_localization
