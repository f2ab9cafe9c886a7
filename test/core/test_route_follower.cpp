// The route follower's controller (route_follower.h): commands, safety sequence, rate limits, end of
// route and watchdog, fed with explicit times and checked against numbers worked out by hand.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

#include "along_route_localization/route_follower.h"

namespace arl = along_route_localization;

// Sums of a few decimal fractions: equal up to rounding.
#define EXPECT_CLOSE(expected, actual) EXPECT_NEAR(expected, actual, 1e-12)

namespace
{

arl::TaughtMotion motion(double linear_mps, double angular_rps, double distance_m = 0.0)
{
  arl::TaughtMotion m;
  m.linear_mps = linear_mps;
  m.angular_rps = angular_rps;
  m.distance_m = distance_m;
  return m;
}

arl::FollowerInput tracking(int keyframe, double confidence, double homing_angle_rad,
                            arl::LocalizationStatus status = arl::LocalizationStatus::kTracking)
{
  arl::FollowerInput input;
  input.status = status;
  input.keyframe = keyframe;
  input.confidence = confidence;
  input.homing_angle_rad = homing_angle_rad;
  return input;
}

// No filter, no practical rate limit (the most of the working range): the command is the target.
arl::RouteFollowerParams immediate()
{
  arl::RouteFollowerParams params;
  params.homing_time_constant_s = 0.0;
  params.max_linear_accel = 100.0;
  params.max_linear_decel = 100.0;
  params.max_angular_accel = 100.0;
  return params;
}

// The creep tests' route: keyframes 0.5 m apart, the taught turn rate 0.25 rad/s per keyframe index. With
// creepParams a creep goes at half the taught 1 m/s, so a command every 0.125 s moves the robot
// 0.5 m/s x 0.125 s = 0.0625 m (all exact in binary), for at most 1 m.
std::vector<arl::TaughtMotion> creepRoute()
{
  std::vector<arl::TaughtMotion> taught;
  for (int k = 0; k < 5; ++k)
    taught.push_back(motion(1.0, 0.25 * k, k == 0 ? 0.0 : 0.5));
  return taught;
}

arl::RouteFollowerParams creepParams()
{
  arl::RouteFollowerParams params = immediate();
  params.min_confidence = 0.5;
  params.slow_factor = 0.5;
  params.recovery_distance_m = 1.0;
  return params;
}

arl::RouteFollower started(const std::vector<arl::TaughtMotion>& taught, const arl::RouteFollowerParams& params)
{
  arl::RouteFollower follower(taught, params);
  std::string message;
  EXPECT_TRUE(follower.start(0.0, &message)) << message;
  return follower;
}

}  // namespace

TEST(RouteFollower, CommandIsTaughtMotionTimesSpeedFactorPlusGainTimesHoming)
{
  arl::RouteFollowerParams params = immediate();
  params.speed_factor = 0.5;
  params.homing_gain = 2.0;
  params.max_homing_turn_rps = 1.0;
  arl::RouteFollower follower = started({ motion(0.2, 0.0), motion(0.8, 0.1), motion(0.2, 0.0) }, params);
  follower.localization(tracking(1, 0.9, 0.1), 0.0);
  const arl::FollowerCommand command = follower.command(0.1);
  // v = 0.5 * 0.8 = 0.4; w = 0.5 * 0.1 + 2 * 0.1 = 0.25
  EXPECT_CLOSE(0.4, command.linear_mps);
  EXPECT_CLOSE(0.25, command.angular_rps);
  EXPECT_EQ("following", follower.reason());
}

TEST(RouteFollower, HomingTermIsBoundedBothWays)
{
  arl::RouteFollowerParams params = immediate();
  params.speed_factor = 0.5;
  params.homing_gain = 2.0;
  params.max_homing_turn_rps = 0.3;
  arl::RouteFollower follower = started({ motion(0.8, 0.1) }, params);
  follower.localization(tracking(0, 0.9, 0.5), 0.0);
  EXPECT_CLOSE(0.05 + 0.3, follower.command(0.1).angular_rps);  // 2 * 0.5 = 1.0, bounded to 0.3
  follower.localization(tracking(0, 0.9, -0.5), 0.2);
  EXPECT_CLOSE(0.05 - 0.3, follower.command(0.3).angular_rps);
}

TEST(RouteFollower, HomingAngleIsLowPassed)
{
  arl::RouteFollowerParams params = immediate();
  params.homing_time_constant_s = 0.3;
  params.homing_gain = 1.0;
  arl::RouteFollower follower = started({ motion(1.0, 0.0) }, params);
  follower.localization(tracking(0, 0.9, 0.0), 0.0);  // the first one is taken as it is
  EXPECT_CLOSE(0.0, follower.filteredHomingAngle());
  follower.localization(tracking(0, 0.9, 0.4), 0.1);  // alpha = 0.1 / (0.3 + 0.1) = 0.25: 0.1
  EXPECT_CLOSE(0.1, follower.filteredHomingAngle());
  follower.localization(tracking(0, 0.9, 0.4), 0.2);  // 0.1 + 0.25 * 0.3 = 0.175
  EXPECT_CLOSE(0.175, follower.filteredHomingAngle());
  EXPECT_CLOSE(0.175, follower.command(0.25).angular_rps);
  // A NaN angle leaves the filter as it was.
  follower.localization(tracking(0, 0.9, std::nan("")), 0.3);
  EXPECT_CLOSE(0.175, follower.filteredHomingAngle());
}

TEST(RouteFollower, SlowsThenStopsWhileConfidenceStaysLowAndResumesWhenItRecovers)
{
  arl::RouteFollowerParams params = immediate();
  params.min_confidence = 0.5;
  params.slow_after_frames = 2;
  params.stop_after_frames = 4;
  params.slow_factor = 0.5;
  arl::RouteFollower follower = started({ motion(1.0, 0.2) }, params);
  const double confidences[] = { 0.9, 0.1, 0.1, 0.1, 0.1, 0.1, 0.9 };
  // low count:                   0    1    2    3    4    5    0
  const double expected_linear[] = { 1.0, 1.0, 0.5, 0.5, 0.0, 0.0, 1.0 };
  double t = 0.0;
  for (int i = 0; i < 7; ++i, t += 0.1)
  {
    follower.localization(tracking(0, confidences[i], 0.0), t);
    const arl::FollowerCommand command = follower.command(t + 0.05);
    EXPECT_CLOSE(expected_linear[i], command.linear_mps) << "localization " << i;
    EXPECT_CLOSE(0.2 * expected_linear[i], command.angular_rps) << "localization " << i;
  }
  follower.localization(tracking(0, 0.1, 0.0), t);
  follower.localization(tracking(0, 0.1, 0.0), t + 0.1);
  follower.command(t + 0.15);
  EXPECT_EQ(0.5, follower.safetyScale());
  EXPECT_NE(std::string::npos, follower.reason().find("slowing")) << follower.reason();
  follower.localization(tracking(0, 0.1, 0.0), t + 0.2);
  follower.localization(tracking(0, 0.1, 0.0), t + 0.3);
  follower.command(t + 0.35);
  EXPECT_EQ(0.0, follower.safetyScale());
  EXPECT_NE(std::string::npos, follower.reason().find("confidence below 0.50 for 4")) << follower.reason();
}

TEST(RouteFollower, StartsSlowUntilTheFirstConfidentLocalizationSinceStartOrTrackBegan)
{
  arl::RouteFollowerParams params = immediate();
  params.min_confidence = 0.5;
  params.slow_after_frames = 2;
  params.stop_after_frames = 3;
  params.slow_factor = 0.25;
  arl::RouteFollower follower = started({ motion(0.8, 0.0) }, params);
  double t = 0.0;
  for (int i = 0; i < 5; ++i, t += 0.1)  // more low ones than stop_after_frames: slow, not stopped
  {
    follower.localization(tracking(0, 0.1, 0.0), t);
    EXPECT_CLOSE(0.2, follower.command(t + 0.05).linear_mps) << "localization " << i;  // 0.25 x 0.8
  }
  EXPECT_NE(std::string::npos, follower.reason().find("starting: slow")) << follower.reason();
  follower.localization(tracking(0, 0.9, 0.0), t);
  EXPECT_CLOSE(0.8, follower.command(t + 0.05).linear_mps);
  const double low_linear[] = { 0.8, 0.2, 0.0 };  // now 2 low ones slow, 3 stop
  for (int i = 0; i < 3; ++i)
  {
    t += 0.1;
    follower.localization(tracking(0, 0.1, 0.0), t);
    EXPECT_CLOSE(low_linear[i], follower.command(t + 0.05).linear_mps) << "low localization " << i;
  }
  // Lost, then the track again: slow until confident, as at the start.
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), t + 0.1);
  EXPECT_CLOSE(0.0, follower.command(t + 0.15).linear_mps);
  follower.localization(tracking(0, 0.1, 0.0), t + 0.2);
  EXPECT_CLOSE(0.2, follower.command(t + 0.25).linear_mps);
  // ~start after a low-confidence stop: slow again (a standing robot would never regain confidence).
  follower.localization(tracking(0, 0.9, 0.0), t + 0.3);
  for (int i = 0; i < 3; ++i)
    follower.localization(tracking(0, 0.1, 0.0), t + 0.4 + 0.1 * i);
  EXPECT_CLOSE(0.0, follower.command(t + 0.65).linear_mps);
  std::string message;
  EXPECT_TRUE(follower.pause(&message));
  EXPECT_TRUE(follower.start(t + 0.7, &message));
  follower.localization(tracking(0, 0.1, 0.0), t + 0.7);
  EXPECT_CLOSE(0.2, follower.command(t + 0.75).linear_mps);
}

TEST(RouteFollower, AKeyframeJumpRampsTheCommandAtTheAccelerationLimits)
{
  arl::RouteFollowerParams params = immediate();
  params.max_linear_accel = 0.5;
  params.max_linear_decel = 0.5;
  params.max_angular_accel = 1.0;
  params.homing_gain = 0.0;
  std::vector<arl::TaughtMotion> taught(11, motion(0.2, 0.0));
  taught[10] = motion(1.0, 0.5);
  arl::RouteFollower follower = started(taught, params);
  follower.localization(tracking(0, 0.9, 0.0), 0.0);
  EXPECT_CLOSE(0.0, follower.command(0.0).linear_mps);  // started at 0: no time to accelerate
  EXPECT_CLOSE(0.2, follower.command(1.0).linear_mps);  // 0.5 m/s^2 x 1 s allows 0.5; target 0.2
  follower.localization(tracking(10, 0.9, 0.0), 1.0);
  arl::FollowerCommand command = follower.command(1.2);  // +0.1 m/s, +0.2 rad/s in 0.2 s
  EXPECT_CLOSE(0.3, command.linear_mps);
  EXPECT_CLOSE(0.2, command.angular_rps);
  command = follower.command(1.4);
  EXPECT_CLOSE(0.4, command.linear_mps);
  EXPECT_CLOSE(0.4, command.angular_rps);
  command = follower.command(1.6);
  EXPECT_CLOSE(0.5, command.linear_mps);
  EXPECT_CLOSE(0.5, command.angular_rps);  // reached
  EXPECT_CLOSE(1.0, follower.target().linear_mps);
  // And back: the jump to keyframe 0 brings the speed down at 0.5 m/s^2 too.
  follower.localization(tracking(0, 0.9, 0.0), 1.6);
  command = follower.command(2.0);
  EXPECT_CLOSE(0.3, command.linear_mps);
  EXPECT_CLOSE(0.1, command.angular_rps);
}

TEST(RouteFollower, BrakesAtTheDecelerationLimitAndSpeedsUpAtTheAccelerationLimit)
{
  arl::RouteFollowerParams params = immediate();
  params.max_linear_accel = 0.5;
  params.max_linear_decel = 2.0;
  params.homing_gain = 0.0;
  // Keyframe 1 was taught backing up.
  arl::RouteFollower follower = started({ motion(1.0, 0.0), motion(-0.3, 0.0) }, params);
  follower.localization(tracking(0, 0.9, 0.0), 0.0);
  EXPECT_CLOSE(0.0, follower.command(0.0).linear_mps);
  EXPECT_CLOSE(0.1, follower.command(0.2).linear_mps);  // speeding up: 0.5 m/s^2 x 0.2 s
  EXPECT_FALSE(follower.braking());
  EXPECT_CLOSE(0.2, follower.command(0.4).linear_mps);
  // Backing up: brake to 0 at 2 m/s^2 (0.1 s), then 0.1 s the other way at 0.5 m/s^2.
  follower.localization(tracking(1, 0.9, 0.0), 0.4);
  EXPECT_CLOSE(-0.05, follower.command(0.6).linear_mps);
  // Slowing while backing up brakes too: the target -0.15 (half speed) from -0.3 in 0.075 s at 2 m/s^2.
  EXPECT_CLOSE(-0.3, follower.command(1.1).linear_mps);
  params.slow_factor = 0.5;
  params.slow_after_frames = 1;
  follower.setParams(params);
  follower.localization(tracking(1, 0.1, 0.0), 1.1);
  EXPECT_CLOSE(-0.2, follower.command(1.15).linear_mps);  // 2 m/s^2 x 0.05 s
  EXPECT_CLOSE(-0.15, follower.command(1.2).linear_mps);
  // A pause stops at 2 m/s^2 too.
  std::string message;
  EXPECT_TRUE(follower.pause(&message)) << message;
  EXPECT_CLOSE(-0.05, follower.command(1.25).linear_mps);
  EXPECT_TRUE(follower.braking());  // backing up counts: the robot still moves
  EXPECT_CLOSE(0.0, follower.command(1.3).linear_mps);
  EXPECT_FALSE(follower.braking());
}

TEST(RouteFollower, StopsAtTheEndOfTheRouteUntilStartedAgain)
{
  arl::RouteFollowerParams params = immediate();
  params.max_linear_accel = 1.0;
  params.max_linear_decel = 1.0;
  arl::RouteFollower follower = started({ motion(0.5, 0.0), motion(0.5, 0.0), motion(0.5, 0.0) }, params);
  follower.localization(tracking(1, 0.9, 0.0), 0.0);
  EXPECT_CLOSE(0.5, follower.command(1.0).linear_mps);
  EXPECT_FALSE(follower.braking());  // at the taught speed
  follower.localization(tracking(2, 0.9, 0.0, arl::LocalizationStatus::kEndOfRoute), 1.0);
  EXPECT_EQ(arl::RouteFollower::State::kFinished, follower.state());
  EXPECT_CLOSE(0.3, follower.command(1.2).linear_mps);  // ramps down at 1 m/s^2
  EXPECT_TRUE(follower.driving());
  EXPECT_TRUE(follower.braking());  // finished, but still moving at 0.3 m/s
  EXPECT_NE(std::string::npos, follower.reason().find("end of the route")) << follower.reason();
  EXPECT_CLOSE(0.0, follower.command(1.6).linear_mps);
  EXPECT_FALSE(follower.driving());
  EXPECT_FALSE(follower.braking());  // at rest
  // Later localizations on the route do not drive again by themselves.
  follower.localization(tracking(1, 0.9, 0.0), 1.7);
  EXPECT_CLOSE(0.0, follower.command(1.8).linear_mps);
  std::string message;
  EXPECT_TRUE(follower.start(1.8, &message)) << message;
  EXPECT_CLOSE(0.1, follower.command(1.9).linear_mps);
}

TEST(RouteFollower, WatchdogStopsWhenLocalizationsStopComing)
{
  arl::RouteFollowerParams params = immediate();
  params.watchdog_timeout_s = 0.5;
  params.max_linear_accel = 2.0;
  params.max_linear_decel = 2.0;
  arl::RouteFollower follower = started({ motion(0.6, 0.0) }, params);
  follower.localization(tracking(0, 0.9, 0.0), 10.0);
  EXPECT_CLOSE(0.6, follower.command(10.5).linear_mps);  // 0.5 s silence: not more than the timeout
  EXPECT_CLOSE(0.4, follower.command(10.6).linear_mps);  // 0.6 s: stop, at 2 m/s^2
  EXPECT_NE(std::string::npos, follower.reason().find("no localization for 0.60 s")) << follower.reason();
  EXPECT_CLOSE(0.0, follower.command(10.9).linear_mps);
  EXPECT_EQ(arl::RouteFollower::State::kFollowing, follower.state());  // still following: resumes by itself
  follower.localization(tracking(0, 0.9, 0.0), 11.0);
  EXPECT_CLOSE(0.4, follower.command(11.1).linear_mps);  // 0.2 s since the last command at 2 m/s^2
}

TEST(RouteFollower, TimeGoingBackStopsUntilTheNextLocalization)
{
  arl::RouteFollowerParams params = immediate();
  params.max_linear_accel = 1.0;
  params.max_linear_decel = 1.0;
  arl::RouteFollower follower = started({ motion(0.6, 0.0) }, params);
  follower.localization(tracking(0, 0.9, 0.0), 100.0);
  EXPECT_CLOSE(0.6, follower.command(100.5).linear_mps);
  // The clock restarts at 1 s: the last localization is "in the future"; the ramp down starts from there.
  EXPECT_CLOSE(0.6, follower.command(1.0).linear_mps);
  EXPECT_NE(std::string::npos, follower.reason().find("time went back")) << follower.reason();
  EXPECT_CLOSE(0.4, follower.command(1.2).linear_mps);
  follower.localization(tracking(0, 0.9, 0.0), 1.3);
  EXPECT_CLOSE(0.6, follower.command(1.4).linear_mps);  // 0.4 + 1 m/s^2 x 0.2 s
  EXPECT_EQ("following", follower.reason());
}

TEST(RouteFollower, TimeJumpingAheadChangesTheCommandByOneBoundedStep)
{
  arl::RouteFollowerParams params = immediate();
  params.max_linear_accel = 1.0;
  params.max_linear_decel = 1.0;
  params.max_angular_accel = 2.0;
  arl::RouteFollower follower = started({ motion(0.6, 0.2) }, params);
  follower.localization(tracking(0, 0.9, 0.0), 0.0);
  EXPECT_CLOSE(0.0, follower.command(0.0, 0.1).linear_mps);
  // 0.05 s later: 1 m/s^2 x 0.05 s and 2 rad/s^2 x 0.05 s.
  arl::FollowerCommand command = follower.command(0.05, 0.1);
  EXPECT_CLOSE(0.05, command.linear_mps);
  EXPECT_CLOSE(0.1, command.angular_rps);
  // The clock jumps 1000 s ahead and a localization comes: one step of at most 0.1 s, not the target.
  follower.localization(tracking(0, 0.9, 0.0), 1000.0);
  command = follower.command(1000.0, 0.1);
  EXPECT_CLOSE(0.15, command.linear_mps);  // 0.05 + 1 m/s^2 x 0.1 s
  EXPECT_CLOSE(0.2, command.angular_rps);  // 0.1 + 2 rad/s^2 x 0.1 s: the target 0.2
  // Without the bound the whole gap counts: the target at once.
  arl::RouteFollower unbounded = started({ motion(0.6, 0.2) }, params);
  unbounded.localization(tracking(0, 0.9, 0.0), 0.0);
  unbounded.command(0.0);
  unbounded.command(0.05);
  unbounded.localization(tracking(0, 0.9, 0.0), 1000.0);
  EXPECT_CLOSE(0.6, unbounded.command(1000.0).linear_mps);
  // A jump ahead with no localization: the watchdog stops the robot, also by one bounded step.
  EXPECT_CLOSE(0.2, follower.command(1000.05, 0.1).linear_mps);  // 0.15 + 1 m/s^2 x 0.05 s
  EXPECT_CLOSE(0.1, follower.command(5000.0, 0.1).linear_mps);   // 0.2 - 1 m/s^2 x 0.1 s
}

TEST(RouteFollower, StopsWhileLostOrInitializingOrOnAKeyframeOutsideTheMap)
{
  arl::RouteFollower follower = started({ motion(0.6, 0.1), motion(0.6, 0.1) }, immediate());
  follower.localization(tracking(1, 0.9, 0.2, arl::LocalizationStatus::kLost), 0.0);
  EXPECT_CLOSE(0.0, follower.command(0.1).linear_mps);
  EXPECT_CLOSE(0.0, follower.command(0.1).angular_rps);
  EXPECT_NE(std::string::npos, follower.reason().find("lost")) << follower.reason();
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kInitializing), 0.2);
  EXPECT_CLOSE(0.0, follower.command(0.3).linear_mps);
  EXPECT_NE(std::string::npos, follower.reason().find("initializing")) << follower.reason();
  follower.localization(tracking(7, 0.9, 0.0), 0.4);
  EXPECT_CLOSE(0.0, follower.command(0.5).linear_mps);
  EXPECT_NE(std::string::npos, follower.reason().find("keyframe 7 is not among the map's 2")) << follower.reason();
  follower.localization(tracking(1, 0.9, 0.0), 0.6);
  EXPECT_CLOSE(0.6, follower.command(0.7).linear_mps);
}

TEST(RouteFollower, StopsOnALocalizationFromAnotherMap)
{
  // The follower's map was taught at 10 s and 10.5 s. A localization of keyframe 1 whose stamp is the
  // follower's drives; one whose stamp differs comes from another map the localizer loaded (its index
  // would drive this map's motion): stop, saying so. A stamp of 0 (unknown) is not checked.
  arl::RouteFollower follower = started({ motion(0.6, 0.1), motion(0.4, 0.0) }, immediate());
  EXPECT_THROW(follower.setKeyframeStamps({ 10000000000LL }), std::invalid_argument);
  follower.setKeyframeStamps({ 10000000000LL, 10500000000LL });
  arl::FollowerInput input = tracking(1, 0.9, 0.0);
  input.keyframe_stamp_ns = 10500000000LL;
  follower.localization(input, 0.0);
  EXPECT_CLOSE(0.4, follower.command(0.1).linear_mps);
  input.keyframe_stamp_ns = 20500000000LL;
  follower.localization(input, 0.2);
  EXPECT_CLOSE(0.0, follower.command(0.3).linear_mps);
  EXPECT_NE(std::string::npos, follower.reason().find("at 20.500 s in the localizer's map, at 10.500 s in the "
                                                      "follower's: they are different maps"))
      << follower.reason();
  // Keyframe 0 from the other map, then lost: no creep along this map's motion from keyframe 0 (at
  // slow_factor 0.5 x 0.4 m/s, recovery_distance 3 m), and an end of the route from the other map finishes
  // nothing: stopped until a localization from this map comes.
  arl::FollowerInput other = tracking(0, 0.9, 0.0);
  other.keyframe_stamp_ns = 99000000000LL;
  follower.localization(other, 0.3);
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.4);
  EXPECT_CLOSE(0.0, follower.command(0.5).linear_mps);
  EXPECT_NE(std::string::npos, follower.reason().find("different maps")) << follower.reason();
  input.status = arl::LocalizationStatus::kEndOfRoute;
  follower.localization(input, 0.6);
  EXPECT_CLOSE(0.0, follower.command(0.7).linear_mps);
  EXPECT_EQ(arl::RouteFollower::State::kFollowing, follower.state());
  input.status = arl::LocalizationStatus::kTracking;
  input.keyframe_stamp_ns = 10500000000LL;
  follower.localization(input, 0.8);
  EXPECT_CLOSE(0.4, follower.command(0.9).linear_mps);
  input.keyframe_stamp_ns = 0;
  follower.localization(input, 1.0);
  EXPECT_CLOSE(0.4, follower.command(1.1).linear_mps);
  // The other map again, then a keyframe beyond this map's 2: stopped, naming the keyframe it could check.
  follower.localization(other, 1.2);
  arl::FollowerInput beyond = tracking(5, 0.9, 0.0);
  beyond.keyframe_stamp_ns = 99000000000LL;
  follower.localization(beyond, 1.3);
  EXPECT_CLOSE(0.0, follower.command(1.35).linear_mps);
  EXPECT_NE(std::string::npos, follower.reason().find("keyframe 0 was taught at 99.000 s")) << follower.reason();
  // This map again, with low confidence: the track began again, so slow_factor (0.5 x 0.4 m/s) until a
  // confident answer, not full speed.
  arl::FollowerInput unsure = tracking(1, 0.1, 0.0);
  unsure.keyframe_stamp_ns = 10500000000LL;
  follower.localization(unsure, 1.4);
  EXPECT_CLOSE(0.2, follower.command(1.5).linear_mps);

  // A map taught from frames without stamps (0): nothing to check, every localization drives.
  arl::RouteFollower unstamped = started({ motion(0.6, 0.1), motion(0.4, 0.0) }, immediate());
  unstamped.setKeyframeStamps({ 0, 0 });
  unstamped.localization(other, 0.0);
  EXPECT_CLOSE(0.6, unstamped.command(0.1).linear_mps);
}

TEST(RouteFollower, ACreepCountsAStalledControllersWholeGapAsDriven)
{
  // creepRoute and creepParams: a creep at 0.5 m/s for at most 1 m, 0.05 m per command 0.1 s apart; then
  // the controller stalls for 10 s (a bounded ramp step of 0.1 s) while the robot may have driven on at its
  // last command: 0.5 m/s x 10 s = 5 m more counted (0.05 with the step), past the recovery distance.
  arl::RouteFollower follower = started(creepRoute(), creepParams());
  follower.localization(tracking(1, 0.9, 0.0), 0.0);
  follower.command(0.0, 0.1);
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.05);
  EXPECT_CLOSE(0.5, follower.command(0.1, 0.1).linear_mps);
  EXPECT_TRUE(follower.creeping());
  EXPECT_CLOSE(0.05, follower.creptDistance());
  follower.command(0.2, 0.1);
  EXPECT_CLOSE(0.1, follower.creptDistance());
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 10.15);
  follower.command(10.2, 0.1);
  EXPECT_NEAR(5.1, follower.creptDistance(), 1e-9);
  follower.command(10.3, 0.1);
  EXPECT_FALSE(follower.creeping());
  EXPECT_NE(std::string::npos, follower.reason().find("crept")) << follower.reason();
}

TEST(RouteFollower, AfterALossOrALowConfidenceStopItCreepsABoundedDistanceAlongTheTaughtMotionThenStops)
{
  // creepRoute, creepParams: 0.0625 m a command every 0.125 s, at most 1 m.
  arl::RouteFollower follower = started(creepRoute(), creepParams());
  follower.localization(tracking(1, 0.9, 0.1), 0.0);
  const arl::FollowerCommand tracked = follower.command(0.125);
  EXPECT_CLOSE(1.0, tracked.linear_mps);
  EXPECT_CLOSE(0.25 + 0.3, tracked.angular_rps);  // taught + 3 x 0.1 homing
  // 16 creeping commands from keyframe 1 (the last one tracked), without the homing term, with the motion
  // taught on the way to the next keyframe (recorded at that one): the first 8 before the robot has crept
  // the 0.5 m to keyframe 2 (keyframe 2's motion), the next 8 after (keyframe 3's); then 1 m is crept and
  // it stops.
  for (int n = 1; n <= 17; ++n)
  {
    const double t = 0.125 * (n + 1);
    follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), t - 0.01);
    const arl::FollowerCommand command = follower.command(t);
    const double expected_linear = n <= 16 ? 0.5 : 0.0;
    const double expected_angular = n <= 8 ? 0.5 * 0.5 : (n <= 16 ? 0.5 * 0.75 : 0.0);
    EXPECT_CLOSE(expected_linear, command.linear_mps) << "command " << n;
    EXPECT_CLOSE(expected_angular, command.angular_rps) << "command " << n;
    EXPECT_EQ(n <= 16, follower.creeping()) << "command " << n << ": " << follower.reason();
  }
  EXPECT_CLOSE(1.0, follower.creptDistance());
  EXPECT_NE(std::string::npos, follower.reason().find("stopped: the localization is lost (crept 1.00 m"))
      << follower.reason();
  EXPECT_CLOSE(0.0, follower.command(3.0).linear_mps);  // and stays stopped
  // The track found again, confidently: full speed, and a later stop may creep again, from there.
  follower.localization(tracking(3, 0.9, 0.0), 3.1);
  EXPECT_CLOSE(1.0, follower.command(3.125).linear_mps);
  EXPECT_CLOSE(0.75, follower.command(3.125).angular_rps);
  for (int i = 0; i < 8; ++i)  // stop_after_frames low ones in a row: 8
    follower.localization(tracking(3, 0.1, 0.0), 3.13 + 0.01 * i);
  const arl::FollowerCommand creep = follower.command(3.25);
  EXPECT_CLOSE(0.5, creep.linear_mps);
  EXPECT_CLOSE(0.5 * 1.0, creep.angular_rps);  // keyframe 4's motion
  EXPECT_NE(std::string::npos, follower.reason().find("creeping: confidence below 0.50 for 8")) << follower.reason();
  EXPECT_CLOSE(0.5 * 0.125, follower.creptDistance());
}

TEST(RouteFollower, ACreepWaitsWhileTheViewIsFeaturelessThenGoesOnWithTheDistanceLeft)
{
  // creepRoute, creepParams: 0.0625 m a command every 0.125 s, at most 1 m.
  arl::RouteFollower follower = started(creepRoute(), creepParams());
  follower.localization(tracking(1, 0.9, 0.0), 0.0);
  EXPECT_CLOSE(1.0, follower.command(0.125).linear_mps);
  arl::FollowerInput lost = tracking(1, 0.0, 0.0, arl::LocalizationStatus::kLost);
  follower.localization(lost, 0.2);
  EXPECT_CLOSE(0.5, follower.command(0.25).linear_mps);
  EXPECT_CLOSE(0.0625, follower.creptDistance());
  // The camera covered: the creep waits, and the distance crept stays.
  arl::FollowerInput covered = lost;
  covered.informative = false;
  follower.localization(covered, 0.3);
  EXPECT_CLOSE(0.0, follower.command(0.375).linear_mps);
  EXPECT_CLOSE(0.0, follower.command(0.5).linear_mps);
  EXPECT_FALSE(follower.creeping());
  EXPECT_NE(std::string::npos, follower.reason().find("featureless")) << follower.reason();
  EXPECT_CLOSE(0.0625, follower.creptDistance());
  // The view back: the same creep goes on, from the same keyframe, with the 0.9375 m left: 15 commands.
  int creeping_commands = 0;
  double t = 0.5;
  for (int n = 0; n < 20; ++n)
  {
    t += 0.125;
    follower.localization(lost, t - 0.01);
    const arl::FollowerCommand command = follower.command(t);
    if (command.linear_mps > 0.0)
    {
      ++creeping_commands;
      // from keyframe 1 (keyframe 2's motion) until 0.5 m are crept, then from 2 (keyframe 3's)
      const double crept_before = follower.creptDistance() - 0.0625;
      EXPECT_CLOSE(crept_before < 0.5 ? 0.25 : 0.375, command.angular_rps) << "command " << n;
    }
  }
  EXPECT_EQ(15, creeping_commands);
  EXPECT_CLOSE(1.0, follower.creptDistance());
}

TEST(RouteFollower, ACreepPassesTheKeyframesTheTeachTookStandingAndReckonsNothingWithoutDistances)
{
  // Keyframes 2 and 3 were taken while the teach robot stood (distance 0, speed 0): lost at keyframe 1,
  // the creep drives with keyframe 4's motion (the way on from the stop), at half of it.
  std::vector<arl::TaughtMotion> taught = { motion(1.0, 0.0), motion(1.0, 0.0, 0.5), motion(0.0, 0.0, 0.0),
                                            motion(0.0, 0.0, 0.0), motion(0.8, 0.5, 0.5), motion(1.0, 0.0, 0.5) };
  arl::RouteFollower follower = started(taught, immediate());
  follower.localization(tracking(1, 0.9, 0.0), 0.0);
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.1);
  const arl::FollowerCommand creep = follower.command(0.2);
  EXPECT_CLOSE(0.4, creep.linear_mps);
  EXPECT_CLOSE(0.25, creep.angular_rps);
  EXPECT_NE(std::string::npos, follower.reason().find("reckoned keyframe 3")) << follower.reason();
  // No distances recorded: the creep stays with the motion taught after its anchor, however far it creeps.
  std::vector<arl::TaughtMotion> no_distances = { motion(1.0, 0.0), motion(1.0, 0.1), motion(1.0, 0.2) };
  arl::RouteFollower blind = started(no_distances, immediate());
  blind.localization(tracking(0, 0.9, 0.0), 0.0);
  blind.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.1);
  for (int n = 1; n <= 10; ++n)
  {
    blind.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.05 + 0.25 * n);
    EXPECT_CLOSE(0.5 * 0.1, blind.command(0.1 + 0.25 * n).angular_rps) << "command " << n;
  }
  EXPECT_CLOSE(0.5 * 2.6, blind.creptDistance());  // at 0.5 m/s from the start (0 s) to the last command
}

TEST(RouteFollower, ARecoveryDistanceOfZeroOrNoTrackedKeyframeStopsAtOnce)
{
  std::vector<arl::TaughtMotion> taught = { motion(1.0, 0.0), motion(1.0, 0.0, 0.5), motion(1.0, 0.0, 0.5) };
  arl::RouteFollowerParams params = immediate();
  params.recovery_distance_m = 0.0;
  arl::RouteFollower follower = started(taught, params);
  follower.localization(tracking(1, 0.9, 0.0), 0.0);
  follower.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.1);
  EXPECT_CLOSE(0.0, follower.command(0.2).linear_mps);
  EXPECT_EQ("stopped: the localization is lost", follower.reason());
  // Lost before any keyframe was tracked: nowhere to creep from.
  arl::RouteFollower fresh = started(taught, immediate());
  fresh.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.0);
  EXPECT_CLOSE(0.0, fresh.command(0.1).linear_mps);
  EXPECT_FALSE(fresh.creeping());
  // The creep never runs past the last keyframe: from the last one it stops at once.
  arl::RouteFollower near_end = started(taught, immediate());
  near_end.localization(tracking(2, 0.9, 0.0), 0.0);
  near_end.localization(tracking(-1, 0.0, 0.0, arl::LocalizationStatus::kLost), 0.1);
  EXPECT_CLOSE(0.0, near_end.command(0.2).linear_mps);
  EXPECT_EQ("stopped: the localization is lost", near_end.reason());
}

TEST(RouteFollower, ServicesStartPauseStop)
{
  arl::RouteFollower follower({ motion(0.5, 0.0) }, immediate());
  std::string message;
  follower.localization(tracking(0, 0.9, 0.0), 0.0);
  EXPECT_EQ(arl::RouteFollower::State::kIdle, follower.state());
  EXPECT_CLOSE(0.0, follower.command(0.1).linear_mps);  // idle: never drives
  EXPECT_FALSE(follower.driving());
  EXPECT_FALSE(follower.pause(&message));
  EXPECT_FALSE(follower.stop(&message));
  EXPECT_TRUE(follower.start(0.1, &message));
  EXPECT_EQ("started following", message);
  EXPECT_FALSE(follower.start(0.1, &message));
  EXPECT_CLOSE(0.25, follower.command(0.15).linear_mps);  // slow until a confident localization since start
  follower.localization(tracking(0, 0.9, 0.0), 0.15);
  EXPECT_CLOSE(0.5, follower.command(0.2).linear_mps);
  EXPECT_TRUE(follower.pause(&message));
  EXPECT_EQ(arl::RouteFollower::State::kPaused, follower.state());
  EXPECT_CLOSE(0.0, follower.command(0.3).linear_mps);
  EXPECT_TRUE(follower.start(0.3, &message));
  EXPECT_EQ("resumed following", message);
  follower.localization(tracking(0, 0.9, 0.0), 0.3);
  EXPECT_CLOSE(0.5, follower.command(0.4).linear_mps);
  EXPECT_TRUE(follower.stop(&message));
  EXPECT_EQ(arl::RouteFollower::State::kStopped, follower.state());
  EXPECT_CLOSE(0.0, follower.command(0.5).linear_mps);
  EXPECT_FALSE(follower.stop(&message));
  EXPECT_TRUE(follower.start(0.5, &message));
}

TEST(RouteFollower, RefusesAMapWithoutMotionAndInvalidParameters)
{
  EXPECT_THROW(arl::RouteFollower{ std::vector<arl::TaughtMotion>() }, std::invalid_argument);
  arl::RouteFollowerParams params;
  params.stop_after_frames = 1;
  params.slow_after_frames = 2;
  EXPECT_EQ("stop_after_frames must be >= slow_after_frames (2), got 1", params.validate());
  EXPECT_THROW((arl::RouteFollower{ { motion(1.0, 0.0) }, params }), std::invalid_argument);
  arl::RouteFollower follower({ motion(1.0, 0.0) });
  arl::RouteFollowerParams negative;
  negative.max_linear_accel = 0.0;
  EXPECT_THROW(follower.setParams(negative), std::invalid_argument);
  EXPECT_CLOSE(0.5, follower.params().max_linear_accel);  // the old ones stay
  EXPECT_EQ("max_linear_accel must be in 0.001 .. 100 m/s^2, got 0", negative.validate());
  EXPECT_EQ("", arl::RouteFollowerParams().validate());
  // The ranges are the parameter table's, under the names users give (not the fields' names).
  arl::RouteFollowerParams fast;
  fast.max_homing_turn_rps = 10.5;
  EXPECT_EQ("max_homing_turn_rate must be in 0 .. 10 rad/s, got 10.5", fast.validate());
  fast.max_homing_turn_rps = 10.0;
  fast.watchdog_timeout_s = std::nan("");
  EXPECT_EQ("watchdog_timeout must be in 0.01 .. 60 s, got nan", fast.validate());
}

TEST(TaughtMotion, KeyframesWithoutARecordTakeTheNearestRecordedOne)
{
  std::map<int, arl::TaughtMotion> recorded;
  recorded[2] = motion(0.1, 0.0);
  recorded[5] = motion(0.5, 0.0);
  const std::vector<arl::TaughtMotion> full = arl::completeTaughtMotion(recorded, 8);
  ASSERT_EQ(8u, full.size());
  const double expected[] = { 0.1, 0.1, 0.1, 0.1, 0.5, 0.5, 0.5, 0.5 };  // 3: 1 from 2, 2 from 5; 4: the other way
  for (int k = 0; k < 8; ++k)
    EXPECT_CLOSE(expected[k], full[k].linear_mps) << "keyframe " << k;

  std::map<int, arl::TaughtMotion> tie;
  tie[0] = motion(0.1, 0.0);
  tie[2] = motion(0.3, 0.0);
  EXPECT_CLOSE(0.1, arl::completeTaughtMotion(tie, 3)[1].linear_mps);  // the earlier one on a tie

  std::map<int, arl::TaughtMotion> beyond;
  beyond[5] = motion(0.5, 0.0);
  EXPECT_TRUE(arl::completeTaughtMotion(beyond, 3).empty());
  EXPECT_TRUE(arl::completeTaughtMotion(std::map<int, arl::TaughtMotion>(), 3).empty());
  EXPECT_TRUE(arl::completeTaughtMotion(recorded, 0).empty());
}
