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
