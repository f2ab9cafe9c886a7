// Navigation: drive the taught route again from each localization. The paper's second contribution
// steers with the homing angle computed from the match; this controller adds the motion recorded at
// the matched keyframe (the feed-forward) to a proportional turn on the homing angle (the feedback),
// and decides when it is not safe to drive (low confidence, lost, no localization, end of the route).
//
// Time is an argument everywhere (seconds, any epoch): nothing here reads a clock. Time that goes back (a
// restarted clock, a looping bag with sim time) stops the robot until the next localization.
#ifndef ALONG_ROUTE_LOCALIZATION_ROUTE_FOLLOWER_H
#define ALONG_ROUTE_LOCALIZATION_ROUTE_FOLLOWER_H

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "along_route_localization/localizer.h"

namespace along_route_localization
{

/// The robot's motion while the teach took one keyframe: its forward speed (m/s) and turn rate (rad/s,
/// REP-103: positive = left), averaged over the velocity messages since the previous keyframe, and the
/// distance travelled since the previous keyframe (m; 0 for the first keyframe).
struct TaughtMotion
{
  double linear_mps = 0.0;
  double angular_rps = 0.0;
  double distance_m = 0.0;
};

/// The motion of each of `keyframes` keyframes from the ones recorded (keyframe index -> motion): a
/// keyframe without a record takes the one of the nearest recorded keyframe (the earlier one on a tie),
/// e.g. the keyframes taken before the velocity topic first spoke. Empty when nothing was recorded or
/// keyframes is 0; records of indices >= keyframes are ignored.
std::vector<TaughtMotion> completeTaughtMotion(const std::map<int, TaughtMotion>& recorded, size_t keyframes);

/// Physical quantities a user can reason about; cfg/RouteFollower.cfg exposes them all. Their names as users
/// give them, working ranges, units and docs are rows of the parameter table (parameters.h, group
/// kRouteFollower); the defaults are these initializers.
struct RouteFollowerParams
{
  double homing_gain = 3.0;             ///< rad/s of turn per rad of homing angle
  double max_homing_turn_rps = 0.5;     ///< bound of the homing term |gain x angle|, rad/s
  double homing_time_constant_s = 0.3;  ///< first-order low-pass of the homing angle, s (0 = none)
  double speed_factor = 1.0;            ///< forward speed = taught speed x this (and the taught turn rate too)
  /// a localization below this counts as low confidence (the localizer publishes the probability of being
  /// within one keyframe: with its shipped calibration 0.85 is a posterior mass of about 0.33 there)
  double min_confidence = 0.85;
  int slow_after_frames = 3;            ///< consecutive low-confidence localizations before slowing
  int stop_after_frames = 8;            ///< consecutive low-confidence localizations before stopping
  double slow_factor = 0.5;             ///< fraction of the speed while slowing
  /// After a stop for low confidence or a loss, creep on at most this far (m; 0 = stop at once): a robot that
  /// stands brings the localizer no new view, so it could never find the route again.
  double recovery_distance_m = 3.0;
  double watchdog_timeout_s = 1.0;      ///< stop when no localization came for this long, s
  double max_linear_accel = 0.5;        ///< bound of the rise of the forward speed |v|, m/s^2
  double max_linear_decel = 0.5;        ///< bound of the fall of the forward speed |v| (braking, a stop), m/s^2
  double max_angular_accel = 1.0;       ///< bound of the change of the turn rate, rad/s^2

  /// Empty when valid, else a sentence naming the first parameter outside its table range (by the name users
  /// give it), or stop_after_frames below slow_after_frames.
  std::string validate() const;
};

/// One localization as the follower reads it (Localization.msg).
struct FollowerInput
{
  LocalizationStatus status = LocalizationStatus::kInitializing;
  int keyframe = -1;
  double confidence = 0.0;
  double homing_angle_rad = 0.0;  ///< REP-103: positive = turn left to get back onto the route
  bool informative = true;        ///< false for a featureless camera frame (dark, blank, covered)
  /// The teach-run stamp of that keyframe in the localizer's map (Localization.keyframe_stamp, ns); 0 when
  /// unknown (not checked).
  int64_t keyframe_stamp_ns = 0;
};

/// A velocity command (geometry_msgs/Twist linear.x, angular.z).
struct FollowerCommand
{
  double linear_mps = 0.0;
  double angular_rps = 0.0;
};

/// The controller. Its command at time t is the target
///   v = s * speed_factor * v_taught[k]
///   w = s * (speed_factor * w_taught[k] + clamp(homing_gain * h_filtered, +-max_homing_turn_rps))
/// (k the matched keyframe, h_filtered the low-passed homing angle, s the safety scale: 1, slow_factor
/// after slow_after_frames low-confidence localizations in a row, 0 after stop_after_frames, while lost or
/// initializing, at the end of the route, and when localizations stopped coming; slow_factor, never 0 for
/// low confidence, until the first confident localization after start() or after the track began: the
/// robot standing still shows the localizer no new view, so a stop there would never end, and its
/// loss detection stops the robot if no confident answer comes), approached from the previous command at
/// no more than max_linear_accel (speeding up) or max_linear_decel (slowing down) and max_angular_accel: a
/// jump of the matched keyframe or a stop never makes a jump in the command. The taught turn rate is scaled
/// like the speed so that the path keeps the taught curvature. A stop for low confidence or a loss comes
/// after a creep (creepOrStop): s = slow_factor, the motion taught on from the last tracked keyframe
/// reckoned by the distance crept, no homing term, at most recovery_distance_m, waiting while the view is
/// featureless; a standing robot would bring the localizer no new view to find the route again.
///
/// States: idle (before start), following, paused, stopped (~stop), finished (end of the route). Only
/// following drives; the others ramp the command down to zero.
class RouteFollower
{
public:
  enum class State
  {
    kIdle,
    kFollowing,
    kPaused,
    kStopped,
    kFinished
  };

  /// motion: one per keyframe of the map (completeTaughtMotion). Throws std::invalid_argument when empty
  /// or when params are invalid.
  explicit RouteFollower(std::vector<TaughtMotion> motion, const RouteFollowerParams& params = RouteFollowerParams());

  /// Throws std::invalid_argument when invalid (the old ones stay).
  void setParams(const RouteFollowerParams& params);
  /// The teach-run stamp of each keyframe of the follower's map (one per keyframe of the motion; throws
  /// std::invalid_argument otherwise). A localization whose keyframe_stamp_ns and its keyframe's stamp here
  /// are both known (not 0) and differ comes from another map: the robot stops (its index would drive this
  /// map's motion), and stays stopped, lost localizations included, until one from this map comes.
  void setKeyframeStamps(std::vector<int64_t> stamps_ns);
  const RouteFollowerParams& params() const { return params_; }

  /// Services. Each returns whether it changed the state and says what happened in `message`.
  /// start: from idle, paused, stopped or finished; clears the low-confidence count and the filter.
  bool start(double now_s, std::string* message);
  /// pause: from following; start resumes.
  bool pause(std::string* message);
  /// stop: from any state but stopped and idle.
  bool stop(std::string* message);

  /// A localization received at now_s. Its status END_OF_ROUTE finishes the route.
  void localization(const FollowerInput& input, double now_s);

  /// The command to send at now_s (call at the control rate). The rate limits act over the time since
  /// the previous call, at most max_step_s: a longer gap (the clock jumped ahead, the controller stalled)
  /// changes the command by one step of max_step_s, never straight to the target (the nodelet passes two
  /// control periods). Infinity: the whole gap. A creep counts the whole gap as driven.
  FollowerCommand command(double now_s, double max_step_s = std::numeric_limits<double>::infinity());

  State state() const { return state_; }
  /// Why the target is what it is: "following", "slowing: ...", "stopped: ...".
  const std::string& reason() const { return reason_; }
  /// The target of the last command() before the rate limits, and the safety scale s in it.
  const FollowerCommand& target() const { return target_; }
  double safetyScale() const { return scale_; }
  /// True while the follower should publish: following, or still ramping down to zero.
  bool driving() const;
  /// True while the target is a standstill (stopped, paused, finished or a following stop) but the last
  /// command still moves: the rate limits are bringing the robot to rest. reason() says why it stops.
  bool braking() const;
  int lowConfidenceFrames() const { return low_frames_; }
  double filteredHomingAngle() const { return homing_filtered_rad_; }
  /// True while the target is a recovery creep; the distance crept since the last confident localization.
  bool creeping() const { return creeping_; }
  double creptDistance() const { return crept_m_; }
  size_t keyframes() const { return motion_.size(); }
  int lastKeyframe() const { return have_input_ ? last_input_.keyframe : -1; }

private:
  void computeTarget(double now_s);
  /// The target instead of a stop for `why`: a creep while the recovery distance lasts, else a stop.
  void creepOrStop(const std::string& why);
  /// Where the creep has brought the robot: the anchor keyframe advanced by the distance crept, keyframe by
  /// keyframe with the taught distances (the creep drives with the motion recorded at the next one).
  size_t creepKeyframe() const;
  void setTarget(const TaughtMotion& taught, double homing_rps);

  std::vector<TaughtMotion> motion_;
  std::vector<int64_t> stamps_ns_;  // of the keyframes, when given (setKeyframeStamps)
  int64_t foreign_stamp_ns_ = 0;     // the last on-route localization came from another map: its stamp (else 0)
  int foreign_keyframe_ = -1;        // and its keyframe
  bool has_distances_ = false;  // some keyframe records a distance travelled (the creep can reckon on)
  RouteFollowerParams params_;
  State state_ = State::kIdle;
  std::string reason_ = "idle: call start";

  bool have_input_ = false;
  FollowerInput last_input_;
  double last_input_s_ = 0.0;
  bool last_on_route_ = false;  // the last localization was on this map's route (tracking or its end)
  double homing_filtered_rad_ = 0.0;
  int low_frames_ = 0;
  bool confident_since_start_ = false;  // a confident localization since start() or since the track began
  int last_on_route_keyframe_ = -1;     // the keyframe of the last tracking (or end of route) localization
  bool creeping_ = false;               // the last target was a recovery creep
  bool creep_begun_ = false;            // a creep has begun (and its anchor is set) since the last drive on the track
  int creep_anchor_ = -1;               // the keyframe the creep started from
  double anchor_crept_m_ = 0.0;         // crept_m_ when it started from there
  double crept_m_ = 0.0;                // commanded distance crept since the last confident localization

  FollowerCommand target_, command_;
  double scale_ = 0.0;
  bool have_command_time_ = false;
  double command_s_ = 0.0;
};

std::string toString(RouteFollower::State state);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROUTE_FOLLOWER_H
