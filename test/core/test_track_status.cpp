// Step 5, status decisions (track_status.h): confirming a global hypothesis and detecting a lost track,
// frame by frame against sequences worked out by hand.
#include <gtest/gtest.h>

#include "along_route_localization/track_status.h"

namespace arl = along_route_localization;

TEST(GlobalConfirmation, NeedsConsecutiveConfidentAnswersMovingLikeTheRobot)
{
  arl::GlobalConfirmation confirmation(3, 2);  // 3 frames, at most 2 keyframes per frame
  EXPECT_FALSE(confirmation.update(100, true, true));  // 1
  EXPECT_FALSE(confirmation.update(102, true, true));  // +2: 2
  EXPECT_TRUE(confirmation.update(102, true, true));   // +0 (a stop): 3
  confirmation.clear();
  EXPECT_FALSE(confirmation.update(100, true, true));  // 1
  EXPECT_FALSE(confirmation.update(103, true, true));  // +3 > s: starts again at 103 -> 1
  EXPECT_FALSE(confirmation.update(99, true, true));   // backwards: 1
  EXPECT_FALSE(confirmation.update(100, false, true)); // not confident: 0
  EXPECT_FALSE(confirmation.update(100, true, true));  // 1
  EXPECT_FALSE(confirmation.update(101, true, true));  // 2
  EXPECT_TRUE(confirmation.update(102, true, true));   // 3
  EXPECT_EQ(3, confirmation.count());
}

TEST(GlobalConfirmation, FeaturelessFramesNeitherCountNorBreakButLetTheRobotMove)
{
  arl::GlobalConfirmation confirmation(3, 2);
  EXPECT_FALSE(confirmation.update(10, true, true));   // 1
  EXPECT_FALSE(confirmation.update(500, true, false)); // dark: ignored, whatever its answer
  EXPECT_FALSE(confirmation.update(3, false, false));  // dark and not confident: ignored too
  EXPECT_EQ(1, confirmation.count());
  // Three frames since keyframe 10: up to 3 * 2 = 6 keyframes ahead is consistent.
  EXPECT_FALSE(confirmation.update(16, true, true));   // 2
  EXPECT_FALSE(confirmation.update(19, true, true));   // +3 in one frame: 1
  EXPECT_EQ(1, confirmation.count());
}

TEST(LossDetector, LostWhenEnoughOfTheLastWindowAreLow)
{
  arl::LossDetector loss(3, 5);  // 3 low among the last 5 informative frames
  EXPECT_FALSE(loss.update(false, true));  // L        1 low
  EXPECT_FALSE(loss.update(true, true));   // L H      1
  EXPECT_FALSE(loss.update(false, true));  // L H L    2
  EXPECT_FALSE(loss.update(true, true));   // L H L H  2
  EXPECT_FALSE(loss.update(true, true));   // L H L H H = 2, though no two lows were consecutive
  EXPECT_FALSE(loss.update(true, true));   // the first L leaves: H L H H H = 1
  EXPECT_EQ(1, loss.lowFrames());
  EXPECT_FALSE(loss.update(false, true));  // L H H H L = 2
  EXPECT_FALSE(loss.update(false, true));  // H H H L L = 2
  EXPECT_TRUE(loss.update(false, true));   // H H L L L = 3
  loss.clear();
  EXPECT_EQ(0, loss.lowFrames());
  EXPECT_FALSE(loss.update(false, true));
}

TEST(LossDetector, FeaturelessFramesDoNotCount)
{
  arl::LossDetector loss(2, 3);
  EXPECT_FALSE(loss.update(false, true));  // 1 low
  for (int i = 0; i < 100; ++i)            // a long tunnel: not evidence of being lost
    EXPECT_FALSE(loss.update(false, false));
  EXPECT_EQ(1, loss.lowFrames());
  EXPECT_TRUE(loss.update(false, true));   // 2 low among the last 3 informative frames
}

TEST(LossDetector, ConsecutiveRunIsTheWindowOfItsOwnLength)
{
  arl::LossDetector loss(4, 4);  // the old rule: 4 consecutive low frames
  for (int i = 0; i < 3; ++i)
    EXPECT_FALSE(loss.update(false, true));
  EXPECT_FALSE(loss.update(true, true));   // one confident frame
  for (int i = 0; i < 3; ++i)
    EXPECT_FALSE(loss.update(false, true));
  EXPECT_TRUE(loss.update(false, true));
}

TEST(LossDetector, LowFramesAboveTheWindowAreBoundedByIt)
{
  arl::LossDetector loss(10, 3);  // cannot need more low frames than the window holds
  EXPECT_FALSE(loss.update(false, true));
  EXPECT_FALSE(loss.update(false, true));
  EXPECT_TRUE(loss.update(false, true));
}

TEST(FrameClock, LearnsThePeriodThenCountsTheFramesMissedInAGap)
{
  arl::FrameClock clock;
  const int64_t ms = 1000000;
  // 10 Hz with jitter: intervals 100, 98, 103, 100, 99 ms. No gap is judged before 5 intervals.
  int64_t t = 5000 * ms;
  EXPECT_EQ(0, clock.update(t).missed);
  EXPECT_EQ(0.0, clock.periodNs());
  for (int64_t interval : { 100, 98, 103, 100 })
    EXPECT_EQ(0, clock.update(t += interval * ms).missed);
  EXPECT_EQ(0.0, clock.periodNs());                // 4 intervals
  EXPECT_EQ(0, clock.update(t += 99 * ms).missed);
  EXPECT_DOUBLE_EQ(100.0 * ms, clock.periodNs());  // median of 98, 99, 100, 100, 103
  EXPECT_EQ(0, clock.update(t += 140 * ms).missed);  // 1.4 periods: jitter, not a missed frame
  // intervals 98, 99, 100, 100, 103, 140: median (100 + 100) / 2
  EXPECT_DOUBLE_EQ(100.0 * ms, clock.periodNs());
  EXPECT_EQ(1, clock.update(t += 150 * ms).missed);   // 1.5 periods: one frame missed
  EXPECT_EQ(9, clock.update(t += 1000 * ms).missed);  // 10 periods: 9 missed
  const arl::FrameClock::Tick tick = clock.update(t += 100 * ms);
  EXPECT_EQ(0, tick.missed);
  EXPECT_FALSE(tick.went_back);
}

TEST(FrameClock, TimeGoingBackAndUnknownStamps)
{
  arl::FrameClock clock;
  const int64_t ms = 1000000;
  int64_t t = 1000 * ms;
  for (int i = 0; i < 8; ++i)
    clock.update(t += 100 * ms);
  arl::FrameClock::Tick tick;
  // An unknown stamp (0) says nothing, and the stamp after it starts afresh: the frame between came.
  EXPECT_FALSE(clock.update(0).went_back);
  EXPECT_EQ(0, clock.update(0).missed);
  EXPECT_EQ(0, clock.update(t += 300 * ms).missed);
  EXPECT_EQ(0, clock.update(t += 100 * ms).missed);
  // Less than half a period back: a frame out of order, not time going back, and no interval.
  tick = clock.update(t - 40 * ms);
  EXPECT_FALSE(tick.went_back);
  EXPECT_EQ(0, tick.missed);
  EXPECT_EQ(0, clock.update(t += 100 * ms).missed);
  // Back in time (a looping bag): said once; the period is kept, so the next gap is still seen.
  tick = clock.update(200 * ms);
  EXPECT_TRUE(tick.went_back);
  EXPECT_EQ(0, tick.missed);
  EXPECT_FALSE(clock.update(300 * ms).went_back);
  EXPECT_DOUBLE_EQ(100.0 * ms, clock.periodNs());
  EXPECT_EQ(2, clock.update(600 * ms).missed);
  // The same stamp again: no interval, no gap, not back.
  tick = clock.update(600 * ms);
  EXPECT_FALSE(tick.went_back);
  EXPECT_EQ(0, tick.missed);
  // forgetLastStamp: the next stamp starts afresh, whatever it is.
  clock.forgetLastStamp();
  tick = clock.update(100 * ms);
  EXPECT_FALSE(tick.went_back);
  EXPECT_EQ(0, tick.missed);
}

TEST(FrameClock, ARateThatChangesForGoodIsLearnt)
{
  arl::FrameClock clock;
  const int64_t ms = 1000000;
  int64_t t = 0;
  for (int i = 0; i < 16; ++i)
    clock.update(t += 100 * ms);  // 15 intervals of 100 ms
  // The camera goes to 5 Hz: each 200 ms interval looks like a missed frame until 200 ms is the
  // median of the last 15 intervals, after 8 of them.
  int reported = 0;
  for (int i = 0; i < 12; ++i)
    reported += clock.update(t += 200 * ms).missed;
  EXPECT_EQ(8, reported);
  EXPECT_DOUBLE_EQ(200.0 * ms, clock.periodNs());
}
