// The taught route (route_map.h): contiguous keyframe storage, stamps, texture energy, input checks.
#include <cstdint>
#include <cstring>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "along_route_localization/route_map.h"
#include "synthetic_route.h"

namespace arl = along_route_localization;
using synthetic::randomFrame;

TEST(RouteMap, KeyframesAreStoredContiguouslyWithStamps)
{
  arl::RouteMap map{ arl::PreprocessingParams() };
  EXPECT_TRUE(map.empty());
  EXPECT_EQ(64, map.width());
  EXPECT_EQ(32, map.height());
  EXPECT_EQ(2048u, map.keyframeBytes());
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 6; ++k)
  {
    frames.push_back(randomFrame(100 + k));
    map.addKeyframe(frames.back(), 1500000000000000000LL + 100000000LL * k);
  }
  ASSERT_EQ(6u, map.size());
  EXPECT_FALSE(map.empty());
  for (size_t k = 0; k < 6; ++k)
  {
    EXPECT_EQ(map.data() + k * 64 * 32, map.keyframe(k)) << "keyframe " << k;
    EXPECT_EQ(0, std::memcmp(frames[k].data, map.keyframe(k), 2048)) << "keyframe " << k;
    EXPECT_EQ(1500000000000000000LL + 100000000LL * static_cast<int64_t>(k), map.stampNs(k));
    const cv::Mat view = map.keyframeMat(k);
    EXPECT_EQ(CV_8UC1, view.type());
    EXPECT_EQ(32, view.rows);
    EXPECT_EQ(64, view.cols);
    EXPECT_EQ(map.keyframe(k), view.data) << "keyframeMat must be a view, not a copy";
  }
  // A copy: changing the source afterwards does not change the map.
  frames[2].setTo(0);
  EXPECT_NE(0, std::memcmp(frames[2].data, map.keyframe(2), 2048));
}

TEST(RouteMap, RegionOfInterestInputIsCopiedRowByRow)
{
  // A 64 x 32 window of a larger image is not continuous in memory; the map must still hold its bytes.
  const cv::Mat big = randomFrame(7, 40, 80);
  const cv::Mat roi = big(cv::Rect(5, 3, 64, 32));
  ASSERT_FALSE(roi.isContinuous());
  arl::RouteMap map{ arl::PreprocessingParams() };
  map.addKeyframe(roi, 1);
  for (int y = 0; y < 32; ++y)
    EXPECT_EQ(0, std::memcmp(roi.ptr<uint8_t>(y), map.keyframe(0) + y * 64, 64)) << "row " << y;
}

TEST(RouteMap, EnergyIsMeanDeviationFrom128BelowTheSky)
{
  // sky_fraction 0.25 -> 8 sky rows. Rows 0..7 = 0 (they would add 128 each), rows 8..31 = 148:
  // energy = |148 - 128| = 20. Flat 128 -> 0. Rows 8..31 alternating 118 / 138 -> 10.
  arl::PreprocessingParams params;
  params.sky_fraction = 0.25;
  arl::RouteMap map(params);
  EXPECT_EQ(params, map.params());
  cv::Mat sky_and_ground(32, 64, CV_8UC1, cv::Scalar(148));
  sky_and_ground.rowRange(0, 8).setTo(0);
  map.addKeyframe(sky_and_ground, 0);
  map.addKeyframe(cv::Mat(32, 64, CV_8UC1, cv::Scalar(128)), 1);
  cv::Mat alternating(32, 64, CV_8UC1);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x)
      alternating.at<uint8_t>(y, x) = (x % 2) ? 138 : 118;
  map.addKeyframe(alternating, 2);
  EXPECT_FLOAT_EQ(20.0f, map.energy(0));
  EXPECT_FLOAT_EQ(0.0f, map.energy(1));
  EXPECT_FLOAT_EQ(10.0f, map.energy(2));
}

TEST(RouteMap, WrongSizeOrTypeThrowsMapError)
{
  arl::RouteMap map{ arl::PreprocessingParams() };
  EXPECT_THROW(map.addKeyframe(cv::Mat(32, 32, CV_8UC1, cv::Scalar(1)), 0), arl::MapError);
  EXPECT_THROW(map.addKeyframe(cv::Mat(64, 32, CV_8UC1, cv::Scalar(1)), 0), arl::MapError);  // transposed
  EXPECT_THROW(map.addKeyframe(cv::Mat(32, 64, CV_8UC3, cv::Scalar(1, 2, 3)), 0), arl::MapError);
  EXPECT_THROW(map.addKeyframe(cv::Mat(32, 64, CV_16UC1, cv::Scalar(1)), 0), arl::MapError);
  EXPECT_THROW(map.addKeyframe(cv::Mat(32, 64, CV_32FC1, cv::Scalar(0.5)), 0), arl::MapError);
  EXPECT_THROW(map.addKeyframe(cv::Mat(), 0), arl::MapError);
  EXPECT_EQ(0u, map.size());
  // A map of another size accepts its own size only.
  arl::PreprocessingParams small;
  small.output_width = 32;
  small.output_height = 16;
  arl::RouteMap small_map(small);
  small_map.addKeyframe(cv::Mat(16, 32, CV_8UC1, cv::Scalar(128)), 0);
  EXPECT_THROW(small_map.addKeyframe(cv::Mat(32, 64, CV_8UC1, cv::Scalar(128)), 1), arl::MapError);
  EXPECT_EQ(1u, small_map.size());
  EXPECT_EQ(512u, small_map.keyframeBytes());
}
