// DroppedFrames, the record of unused frames behind each nodelet's diagnostics: what it counts, what
// it reports, and which drops it lets the nodelet log.
#include <map>
#include <string>

#include <gtest/gtest.h>

#include "glue/diagnostics.h"

namespace arl = along_route_localization;

namespace
{

std::map<std::string, std::string> reported(const arl::DroppedFrames& dropped, const std::string& noun)
{
  diagnostic_updater::DiagnosticStatusWrapper stat;
  dropped.addTo(stat, noun);
  std::map<std::string, std::string> values;
  for (const diagnostic_msgs::KeyValue& pair : stat.values)
    values[pair.key] = pair.value;
  return values;
}

}  // namespace

TEST(DroppedFrames, CountsSaysTheLastReasonAndLogsEachKindAtOnce)
{
  arl::DroppedFrames dropped;
  EXPECT_FALSE(dropped.newestDropped());
  EXPECT_EQ((std::map<std::string, std::string>{ { "frames dropped", "0" }, { "last dropped frame", "(none)" } }),
            reported(dropped, "frame"));

  EXPECT_TRUE(dropped.drop(1, "a 32x16 frame"));  // the first of its kind is logged
  EXPECT_TRUE(dropped.newestDropped());
  EXPECT_FALSE(dropped.drop(1, "a 16x8 frame"));  // the same kind again within 5 s is not
  EXPECT_TRUE(dropped.drop(2, "a 'bgr8' frame"));  // another kind is, at once
  EXPECT_EQ(3u, dropped.count());
  EXPECT_EQ("a 'bgr8' frame", dropped.lastReason());
  EXPECT_EQ(2, dropped.lastKind());

  dropped.used();  // a good frame: the newest is no longer dropped, the record stays
  EXPECT_FALSE(dropped.newestDropped());
  EXPECT_EQ(3u, dropped.count());
  EXPECT_EQ((std::map<std::string, std::string>{ { "images dropped", "3" }, { "last dropped image", "a 'bgr8' frame" } }),
            reported(dropped, "image"));
  EXPECT_FALSE(dropped.drop(1, "a 32x16 frame"));  // still within 5 s of kind 1's message
  EXPECT_TRUE(dropped.newestDropped());
}

TEST(DroppedFrames, ByKindCountsEachKindWithItsLatestReasonInTheOrderTheyCame)
{
  arl::DroppedFrames dropped;
  EXPECT_EQ("", dropped.byKind("frame"));
  dropped.drop(3, "waiting for the parameters");
  dropped.drop(1, "a 32x16 frame");
  dropped.drop(1, "a 16x8 frame");
  dropped.drop(1, "a 16x8 frame");
  EXPECT_EQ("1 frame: waiting for the parameters; 3 frames: a 16x8 frame", dropped.byKind("frame"));
}
