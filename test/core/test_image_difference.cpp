// Step 2 (image_difference.h): SAD with a horizontal shift search, sub-pixel refinement, census cost,
// texture energy, and a known shift recovered from a real Nordland frame.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <utility>
#include <vector>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>

#include "along_route_localization/image_difference.h"
#include "along_route_localization/preprocessing.h"
#include "synthetic_route.h"
#include "nordland.h"

namespace arl = along_route_localization;
using synthetic::randomBytes;
using synthetic::shiftedRight;

namespace
{



// The 6 x 2 pair used by the hand calculations below.
const uint8_t kTinyQuery[12] = { 10, 20, 30, 40, 50, 60,  //
                                 1,  2,  3,  4,  5,  6 };
const uint8_t kTinyKeyframe[12] = { 12, 22, 28, 44, 50, 70,  //
                                    5,  5,  5,  5,  5,  5 };

}  // namespace

TEST(ImageDifference, SadOnTinyMatricesByHand)
{
  // width 6, height 2, m = 1: query columns 1..4 against keyframe columns 1-d .. 4-d.
  // d = 0: row 0 |20-22|+|30-28|+|40-44|+|50-50| = 8, row 1 |2-5|+|3-5|+|4-5|+|5-5| = 6 -> 14
  // d = +1 (keyframe columns 0..3): row 0 8+8+12+6 = 34, row 1 6 -> 40
  // d = -1 (keyframe columns 2..5): row 0 |20-28|+|30-44|+|40-50|+|50-70| = 52, row 1 6 -> 58
  const arl::ImageDifference difference(6, 2, 0, 1, false);
  EXPECT_EQ(8, difference.comparedPixels());
  EXPECT_EQ(14u, difference.sadAtShift(kTinyQuery, kTinyKeyframe, 0));
  EXPECT_EQ(40u, difference.sadAtShift(kTinyQuery, kTinyKeyframe, 1));
  EXPECT_EQ(58u, difference.sadAtShift(kTinyQuery, kTinyKeyframe, -1));

  // Best shift 0, cost = 14 / 8 compared pixels.
  const arl::ShiftedDifference best = difference.compare(kTinyQuery, kTinyKeyframe);
  EXPECT_FLOAT_EQ(1.75f, best.cost);
  EXPECT_FLOAT_EQ(0.0f, best.shift_px);
}

TEST(ImageDifference, SubpixelShiftIsTheVertexOfTheParabola)
{
  // Parabola through (-1, 58), (0, 14), (1, 40): vertex at
  // (c(-1) - c(1)) / (2 (c(-1) - 2 c(0) + c(1))) = 18 / (2 * 70) = 0.128571. The cost stays 14 / 8.
  const arl::ImageDifference difference(6, 2, 0, 1, true);
  const arl::ShiftedDifference best = difference.compare(kTinyQuery, kTinyKeyframe);
  EXPECT_NEAR(18.0 / 140.0, best.shift_px, 1e-5);
  EXPECT_FLOAT_EQ(1.75f, best.cost);
}

TEST(ImageDifference, BandsTakeEachTheirOwnShiftByHand)
{
  // 8 x 2, m = 1, compared columns 1..6. Row 0 of the query is the keyframe's row 0 moved right by 1, row 1
  // the keyframe's row 1 moved left by 1 (parallax: the two bands moved by different amounts).
  //   keyframe row 0: 0 10 20 30 40 50 60 70      query row 0 (its cols 1..6): 0 10 20 30 40 50
  //   keyframe row 1: 0 5 15 30 50 75 105 140     query row 1 (its cols 1..6): 15 30 50 75 105 140
  // Row 0 against keyframe cols 1-d..6-d: d = +1: 0, d = 0: 6 x 10 = 60, d = -1: 6 x 20 = 120.
  // Row 1: d = -1: 0, d = 0: 10+15+20+25+30+35 = 135, d = +1: 15+25+35+45+55+65 = 240.
  // One shift for both rows: d = -1 (120 + 0 = 120 against 195 and 240), cost 120 / 12 = 10.
  // Two bands, each at its own best: 0 + 0, cost 0; the reported shift is still the whole strip's, -1.
  const uint8_t keyframe[16] = { 0, 10, 20, 30, 40, 50, 60, 70,  //
                                 0, 5,  15, 30, 50, 75, 105, 140 };
  const uint8_t query[16] = { 0,  0,  10, 20, 30, 40,  50,  60,  //
                              5, 15, 30, 50, 75, 105, 140, 140 };
  const arl::ImageDifference one(8, 2, 0, 1, false);
  const arl::ImageDifference two(8, 2, 0, 1, false, 2);
  EXPECT_EQ(1, one.bands());
  EXPECT_EQ(2, two.bands());
  EXPECT_EQ(12, two.comparedPixels());
  EXPECT_FLOAT_EQ(10.0f, one.compare(query, keyframe).cost);
  EXPECT_FLOAT_EQ(-1.0f, one.compare(query, keyframe).shift_px);
  EXPECT_FLOAT_EQ(0.0f, two.compare(query, keyframe).cost);
  EXPECT_FLOAT_EQ(-1.0f, two.compare(query, keyframe).shift_px);
  // A band per row of the tiny pair above: row 0 best at d = 0 (8), row 1 the same 6 at every shift: 8 + 6,
  // the same as one shift.
  EXPECT_FLOAT_EQ(1.75f, arl::ImageDifference(6, 2, 0, 1, false, 2).compare(kTinyQuery, kTinyKeyframe).cost);
  EXPECT_THROW(arl::ImageDifference(8, 2, 0, 1, false, 0), std::invalid_argument);
  EXPECT_THROW(arl::ImageDifference(8, 2, 0, 1, false, 3), std::invalid_argument);  // more bands than rows
  EXPECT_THROW(arl::ImageDifference(8, 4, 2, 1, false, 3), std::invalid_argument);  // 2 rows below the sky
}

TEST(ImageDifference, AVerticalSearchMatchesAnImageMovedDownByARowByHand)
{
  // 6 x 3, m = 1, compared columns 1..4. The query is the keyframe moved down one row (the camera pitched
  // up), a new row 0 on top:
  //   keyframe  row 0: 10 20 30 40 50 60   row 1: 60 50 40 30 20 10   row 2: 5 5 5 5 5 5
  //   query     row 0: 200 x 6             row 1: = keyframe row 0    row 2: = keyframe row 1
  // Level (V = 0), per shift d, rows 0 + 1 + 2 of |query(y, x) - keyframe(y, x - d)| over x = 1..4:
  //   d = -1: (170+160+150+140) + (20+0+20+40) + (45+35+25+15) = 620 + 80 + 120 = 820  <- best, 820 / 12
  //   d =  0: (180+170+160+150) + (30+10+10+30) + 120 = 860;   d = +1: (190+180+170+160) + (40+20+0+20) + 120 = 900
  // With V = 1, at v = +1 query rows 1-2 meet keyframe rows 0-1: 0 at d = 0, over 8 pixels; that wins.
  const uint8_t keyframe[18] = { 10, 20, 30, 40, 50, 60,  //
                                 60, 50, 40, 30, 20, 10,  //
                                 5,  5,  5,  5,  5,  5 };
  const uint8_t query[18] = { 200, 200, 200, 200, 200, 200,  //
                              10,  20,  30,  40,  50,  60,   //
                              60,  50,  40,  30,  20,  10 };
  const arl::ImageDifference level(6, 3, 0, 1, false);
  const arl::ImageDifference vertical(6, 3, 0, 1, false, 1, 1);
  EXPECT_EQ(0, level.maxVerticalShift());
  EXPECT_EQ(1, vertical.maxVerticalShift());
  EXPECT_FLOAT_EQ(820.0f / 12.0f, level.compare(query, keyframe).cost);
  EXPECT_FLOAT_EQ(-1.0f, level.compare(query, keyframe).shift_px);
  EXPECT_FLOAT_EQ(0.0f, vertical.compare(query, keyframe).cost);
  EXPECT_FLOAT_EQ(0.0f, vertical.compare(query, keyframe).shift_px);
  // Moved up instead (the keyframe moved down against the query): v = -1 matches, by symmetry.
  EXPECT_FLOAT_EQ(0.0f, vertical.compare(keyframe, query).cost);
  EXPECT_GT(level.compare(keyframe, query).cost, 50.0f);
  EXPECT_THROW(arl::ImageDifference(6, 3, 0, 1, false, 1, 2), std::invalid_argument);  // 2 of 3 rows: over half
  EXPECT_THROW(arl::ImageDifference(6, 3, 0, 1, false, 1, -1), std::invalid_argument);
}

TEST(ImageDifference, AVerticalSearchWeighsEachBandByItsRowsByHand)
{
  // 6 x 4, m = 1, two bands (rows 0-1, 2-3), V = 1. The keyframe is 0 everywhere and each query row a constant
  // (10, 20, 30, 40), so a row's cost per pixel is its value at every shift. Band 0: v = 0 rows 0-1, 15; v = +1
  // row 1 only (row 0 has no keyframe row above), 20; v = -1 rows 0-1, 15: best 15. Band 1: v = 0 and v = +1
  // rows 2-3, 35; v = -1 row 2 only (row 3 would meet keyframe row 4), 30: best 30. Each band weighs half:
  // 0.5 x 15 + 0.5 x 30 = 22.5. One band: v = -1 rows 0-2, 20; v = 0, 25; v = +1 rows 1-3, 30: best 20.
  const uint8_t keyframe[24] = {};
  uint8_t query[24];
  for (int y = 0; y < 4; ++y)
    std::fill(query + 6 * y, query + 6 * (y + 1), static_cast<uint8_t>(10 * (y + 1)));
  EXPECT_FLOAT_EQ(22.5f, arl::ImageDifference(6, 4, 0, 1, false, 2, 1).compare(query, keyframe).cost);
  EXPECT_FLOAT_EQ(20.0f, arl::ImageDifference(6, 4, 0, 1, false, 1, 1).compare(query, keyframe).cost);
  EXPECT_FLOAT_EQ(25.0f, arl::ImageDifference(6, 4, 0, 1, false, 1, 0).compare(query, keyframe).cost);
}

TEST(ImageDifference, AVerticalSearchFindsTheShiftOfARandomImageMovedBothWays)
{
  // A random 64 x 32 frame moved right by 3 px and down by 2 rows (the rows and columns that come in
  // repeat the edge): level, no shift matches (random pixels decorrelate over one row); with V = 2 the
  // shift 3 at v = +2 matches exactly, in one band or two; with V = 1 it cannot.
  const cv::Mat keyframe = synthetic::randomFrame(7);
  cv::Mat query(32, 64, CV_8UC1);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x)
      query.at<uint8_t>(y, x) = keyframe.at<uint8_t>(std::max(0, y - 2), std::max(0, x - 3));
  const arl::ShiftedDifference level = arl::ImageDifference(64, 32, 0, 4, false).compare(query.data, keyframe.data);
  const arl::ShiftedDifference one = arl::ImageDifference(64, 32, 0, 4, false, 1, 1).compare(query.data, keyframe.data);
  const arl::ShiftedDifference two = arl::ImageDifference(64, 32, 0, 4, false, 1, 2).compare(query.data, keyframe.data);
  const arl::ShiftedDifference bands = arl::ImageDifference(64, 32, 0, 4, false, 2, 2).compare(query.data, keyframe.data);
  EXPECT_GT(level.cost, 40.0f);  // uniform bytes differ by 85 on average
  EXPECT_GT(one.cost, 40.0f);
  EXPECT_FLOAT_EQ(0.0f, two.cost);
  EXPECT_FLOAT_EQ(3.0f, two.shift_px);
  EXPECT_FLOAT_EQ(0.0f, bands.cost);
  EXPECT_FLOAT_EQ(3.0f, bands.shift_px);
  // compareMany gives what compare gives, keyframe by keyframe.
  const cv::Mat other = synthetic::randomFrame(8);
  std::vector<uint8_t> stack(keyframe.data, keyframe.data + 64 * 32);
  stack.insert(stack.end(), other.data, other.data + 64 * 32);
  float costs[2], shifts[2];
  arl::ImageDifference(64, 32, 0, 4, false, 1, 2).compareMany(query.data, stack.data(), 2, costs, shifts);
  EXPECT_FLOAT_EQ(0.0f, costs[0]);
  EXPECT_FLOAT_EQ(3.0f, shifts[0]);
  EXPECT_FLOAT_EQ(arl::ImageDifference(64, 32, 0, 4, false, 1, 2).compare(query.data, other.data).cost, costs[1]);
  EXPECT_GT(costs[1], 40.0f);
}

TEST(ImageDifference, FirstRowSkipsSkyRows)
{
  // Row 0 differs wildly (sky), rows 1-2 are identical: with first_row 1 the cost is 0.
  const uint8_t query[18] = { 0,  255, 0,  255, 0,  255,  //
                              10, 20,  30, 40,  50, 60,   //
                              61, 52,  43, 34,  25, 16 };
  uint8_t keyframe[18];
  for (int i = 0; i < 18; ++i)
    keyframe[i] = query[i];
  for (int x = 0; x < 6; ++x)
    keyframe[x] = static_cast<uint8_t>(255 - query[x]);  // |difference| 255 on every sky pixel
  const arl::ImageDifference with_sky(6, 3, 0, 1, false);
  const arl::ImageDifference without_sky(6, 3, 1, 1, false);
  EXPECT_EQ(12, with_sky.comparedPixels());
  EXPECT_EQ(8, without_sky.comparedPixels());
  EXPECT_EQ(4u * 255u, with_sky.sadAtShift(query, keyframe, 0));
  EXPECT_EQ(0u, without_sky.sadAtShift(query, keyframe, 0));
  const arl::ShiftedDifference best = without_sky.compare(query, keyframe);
  EXPECT_FLOAT_EQ(0.0f, best.cost);
  EXPECT_FLOAT_EQ(0.0f, best.shift_px);
}

TEST(ImageDifference, RecoversSyntheticShiftWithDocumentedSign)
{
  // query(x) = keyframe(x - d): the scene moved d px to the right, so shift_px = +d and SAD(d) = 0
  // (the strip [4, 60) only reads keyframe columns [4 - d, 60 - d), inside the image for |d| <= 4).
  const int width = 64, height = 32;
  const std::vector<uint8_t> keyframe = randomBytes(width * height, 11);
  const arl::ImageDifference integer(width, height, 0, 4, false);
  const arl::ImageDifference subpixel(width, height, 0, 4, true);
  for (int d : { 2, -2, 1, -3 })
  {
    const std::vector<uint8_t> query = shiftedRight(keyframe, width, height, d);
    EXPECT_EQ(0u, integer.sadAtShift(query.data(), keyframe.data(), d)) << "d = " << d;
    const arl::ShiftedDifference exact = integer.compare(query.data(), keyframe.data());
    EXPECT_FLOAT_EQ(static_cast<float>(d), exact.shift_px) << "d = " << d;
    EXPECT_FLOAT_EQ(0.0f, exact.cost) << "d = " << d;
    const arl::ShiftedDifference refined = subpixel.compare(query.data(), keyframe.data());
    EXPECT_NEAR(d, refined.shift_px, 0.5) << "d = " << d;
    EXPECT_FLOAT_EQ(0.0f, refined.cost) << "d = " << d;
  }
}

TEST(ImageDifference, ShiftAtTheEndOfTheRangeStaysInsideIt)
{
  // d = m = 4: the best cost has no neighbour at d = 5, so the answer must stay within [-4, 4].
  const int width = 64, height = 32;
  const std::vector<uint8_t> keyframe = randomBytes(width * height, 12);
  const arl::ImageDifference subpixel(width, height, 0, 4, true);
  for (int d : { 4, -4 })
  {
    const std::vector<uint8_t> query = shiftedRight(keyframe, width, height, d);
    const arl::ShiftedDifference best = subpixel.compare(query.data(), keyframe.data());
    EXPECT_NEAR(d, best.shift_px, 0.5) << "d = " << d;
    EXPECT_LE(std::abs(best.shift_px), 4.0f) << "d = " << d;
    EXPECT_FLOAT_EQ(0.0f, best.cost);
  }
}

TEST(ImageDifference, CompareManyEqualsCompareForEveryKeyframeSerialOrParallel)
{
  // 600 keyframes: from 512 on, compareMany with `parallel` splits them across threads.
  const int width = 64, height = 32, count = 600;
  const std::vector<uint8_t> keyframes = randomBytes(static_cast<size_t>(width) * height * count, 13);
  // A query close to keyframe 20 shifted by 1, so that one keyframe stands out.
  std::vector<uint8_t> keyframe20(keyframes.begin() + 20 * width * height, keyframes.begin() + 21 * width * height);
  const std::vector<uint8_t> query = shiftedRight(keyframe20, width, height, 1);
  for (const std::pair<int, int>& rows_bands : { std::make_pair(0, 1), std::make_pair(5, 1), std::make_pair(0, 2),
                                                  std::make_pair(5, 3) })
  {
    const int first_row = rows_bands.first;
    const arl::ImageDifference difference(width, height, first_row, 4, true, rows_bands.second);
    for (bool parallel : { false, true })
    {
      std::vector<float> costs(count, -1.0f), shifts(count, -99.0f);
      difference.compareMany(query.data(), keyframes.data(), count, costs.data(), shifts.data(), parallel);
      for (int k = 0; k < count; ++k)
      {
        const arl::ShiftedDifference single =
            difference.compare(query.data(), keyframes.data() + static_cast<size_t>(k) * width * height);
        EXPECT_EQ(single.cost, costs[k]) << "keyframe " << k << " parallel " << parallel;
        EXPECT_EQ(single.shift_px, shifts[k]) << "keyframe " << k << " parallel " << parallel;
      }
      EXPECT_FLOAT_EQ(0.0f, costs[20]);
      EXPECT_NEAR(1.0f, shifts[20], 0.5f);
    }
  }
}

TEST(ImageDifference, SadOfNarrowImagesEqualsPlainLoops)
{
  // Narrow images (two strip rows fit one 64-byte register: the coarse global search's 32x16) take
  // another kernel; odd heights leave a single last row, odd first rows start mid-pair. Every shift's
  // SAD must equal the plain loop's.
  const struct
  {
    int width, height, first_row, max_shift;
  } cases[] = { { 32, 16, 1, 2 }, { 32, 15, 0, 2 }, { 32, 16, 3, 4 }, { 24, 9, 2, 3 }, { 20, 7, 0, 1 }, { 33, 16, 1, 2 } };
  for (const auto& c : cases)
  {
    const std::vector<uint8_t> query = randomBytes(static_cast<size_t>(c.width) * c.height, 21);
    const std::vector<uint8_t> keyframe = randomBytes(static_cast<size_t>(c.width) * c.height, 22);
    const arl::ImageDifference difference(c.width, c.height, c.first_row, c.max_shift, false);
    uint32_t best = UINT32_MAX;
    for (int d = -c.max_shift; d <= c.max_shift; ++d)
    {
      uint32_t expected = 0;
      for (int y = c.first_row; y < c.height; ++y)
        for (int x = c.max_shift; x < c.width - c.max_shift; ++x)
          expected += static_cast<uint32_t>(
              std::abs(query[y * c.width + x] - keyframe[y * c.width + x - d]));
      EXPECT_EQ(expected, difference.sadAtShift(query.data(), keyframe.data(), d))
          << c.width << "x" << c.height << " first row " << c.first_row << " m " << c.max_shift << " d " << d;
      best = std::min(best, expected);
    }
    EXPECT_FLOAT_EQ(static_cast<float>(best) / difference.comparedPixels(),
                    difference.compare(query.data(), keyframe.data()).cost);
  }
}

TEST(ImageDifference, HalveImageAveragesTwoByTwoBlocksByHand)
{
  // 5 x 3 -> 2 x 1: the odd last column and row are dropped.
  // block (0,0): 10 + 20 + 30 + 41 = 101 -> (101 + 2) / 4 = 25; block (0,1): 0 + 1 + 255 + 255 = 511 -> 128
  const uint8_t image[15] = { 10, 20, 0,   1,   99,  //
                              30, 41, 255, 255, 99,  //
                              99, 99, 99,  99,  99 };
  uint8_t half[2] = { 7, 7 };
  arl::halveImage(image, 5, 3, half);
  EXPECT_EQ(25, half[0]);
  EXPECT_EQ(128, half[1]);
}

TEST(ImageDifference, HalveImagesEqualsHalveImageOnEachImage)
{
  // Even sizes go through one cv::resize over the stack, odd ones through the loop: the bytes must be
  // halveImage's either way.
  for (const auto& size : { std::make_pair(64, 32), std::make_pair(32, 16), std::make_pair(33, 15) })
  {
    const int width = size.first, height = size.second, count = 37;
    const size_t bytes = static_cast<size_t>(width) * height, half_bytes = static_cast<size_t>(width / 2) * (height / 2);
    const std::vector<uint8_t> images = randomBytes(bytes * count, 31);
    std::vector<uint8_t> stacked(half_bytes * count, 1), single(half_bytes);
    arl::halveImages(images.data(), count, width, height, stacked.data());
    for (int i = 0; i < count; ++i)
    {
      arl::halveImage(images.data() + i * bytes, width, height, single.data());
      EXPECT_TRUE(std::equal(single.begin(), single.end(), stacked.begin() + i * half_bytes))
          << width << "x" << height << " image " << i;
    }
  }
}

TEST(ImageDifference, RandomPairCostIsTheMeanAbsoluteDifference)
{
  // Independent plain loop: cost = min_d SAD(d) / ((h - first_row) * (w - 2m)).
  const int width = 40, height = 12, first_row = 2, m = 3;
  const std::vector<uint8_t> query = randomBytes(width * height, 14);
  const std::vector<uint8_t> keyframe = randomBytes(width * height, 15);
  double best = 1e18;
  for (int d = -m; d <= m; ++d)
  {
    double sad = 0.0;
    for (int y = first_row; y < height; ++y)
      for (int x = m; x < width - m; ++x)
        sad += std::abs(query[y * width + x] - keyframe[y * width + x - d]);
    best = std::min(best, sad);
  }
  const arl::ImageDifference difference(width, height, first_row, m, true);
  EXPECT_NEAR(best / ((height - first_row) * (width - 2 * m)), difference.compare(query.data(), keyframe.data()).cost,
              1e-4);
}

TEST(TextureEnergy, MeanAbsoluteDeviationFrom128ByHand)
{
  // Row 0: |0| + |2| + |-8| + |0| = 10; row 1: |-128| + |127| + 0 + 0 = 255.
  // All rows: 265 / 8 = 33.125. From row 1: 255 / 4 = 63.75.
  const uint8_t image[8] = { 128, 130, 120, 128,  //
                             0,   255, 128, 128 };
  EXPECT_FLOAT_EQ(33.125f, arl::textureEnergy(image, 4, 2, 0));
  EXPECT_FLOAT_EQ(63.75f, arl::textureEnergy(image, 4, 2, 1));
  const std::vector<uint8_t> flat(64 * 32, 128);
  EXPECT_FLOAT_EQ(0.0f, arl::textureEnergy(flat.data(), 64, 32, 0));
}

TEST(Census, TransformOfA3x3ByHand)
{
  // 10 20 30 / 40 50 60 / 70 80 90; bit b = neighbour b (row-major, centre skipped) < centre,
  // edges replicated. Centre 50: 10, 20, 30, 40 are darker -> bits 0-3 -> 15.
  // (0,0) = 10: nothing darker -> 0. (0,1) = 20: up-left (replicated 10) bit 0, left 10 bit 3 -> 9.
  // (1,0) = 40: up-left (replicated 10) bit 0, up 10 bit 1, up-right 20 bit 2 -> 7.
  // (2,2) = 90: 50 b0, 60 b1, 60 (replicated) b2, 80 b3, 80 (replicated, below-left) b5 -> 47.
  const uint8_t image[9] = { 10, 20, 30, 40, 50, 60, 70, 80, 90 };
  uint8_t codes[9];
  arl::censusTransform(image, 3, 3, codes);
  const uint8_t expected[9] = { 0, 9, 9, 7, 15, 15, 7, 47, 47 };
  for (int i = 0; i < 9; ++i)
    EXPECT_EQ(expected[i], codes[i]) << "pixel " << i;

  const uint8_t flat[9] = { 5, 5, 5, 5, 5, 5, 5, 5, 5 };
  arl::censusTransform(flat, 3, 3, codes);
  for (int i = 0; i < 9; ++i)
    EXPECT_EQ(0, codes[i]) << "pixel " << i;
}

TEST(Census, CostIsMeanHammingDistanceWithShiftSearch)
{
  // width 6, height 1, m = 1: query columns 1..4.
  // keyframe codes 01 03 07 0F 1F 3F; query(x) = keyframe(x - 1) -> at d = +1 identical (cost 0);
  // d = 0: each pair differs in one bit -> 1; d = -1: two bits -> 2. Best d = +1, cost 0.
  const uint8_t keyframe[6] = { 0x01, 0x03, 0x07, 0x0F, 0x1F, 0x3F };
  const uint8_t query[6] = { 0xAA, 0x01, 0x03, 0x07, 0x0F, 0x1F };
  const arl::CensusDifference census(6, 1, 0, 1, false);
  const arl::ShiftedDifference best = census.compare(query, keyframe);
  EXPECT_FLOAT_EQ(0.0f, best.cost);
  EXPECT_FLOAT_EQ(1.0f, best.shift_px);

  // Query FF/00 against keyframe 0F everywhere: 4 differing bits at every pixel and shift -> 4.
  const uint8_t query2[6] = { 0x00, 0xFF, 0xFF, 0x00, 0x00, 0xFF };
  const uint8_t keyframe2[6] = { 0x0F, 0x0F, 0x0F, 0x0F, 0x0F, 0x0F };
  EXPECT_FLOAT_EQ(4.0f, census.compare(query2, keyframe2).cost);

  // Keyframe shifted the other way: query(x) = keyframe(x + 1) -> d = -1.
  const uint8_t query3[6] = { 0x03, 0x07, 0x0F, 0x1F, 0x3F, 0xAA };
  const arl::ShiftedDifference left = census.compare(query3, keyframe);
  EXPECT_FLOAT_EQ(0.0f, left.cost);
  EXPECT_FLOAT_EQ(-1.0f, left.shift_px);
}

TEST(ImageDifference, CostFunctionNamesRoundTrip)
{
  for (auto cost : { arl::CostFunction::kSad, arl::CostFunction::kCensus })
  {
    arl::CostFunction parsed = cost == arl::CostFunction::kSad ? arl::CostFunction::kCensus : arl::CostFunction::kSad;
    EXPECT_TRUE(arl::costFunctionFromString(arl::toString(cost), &parsed));
    EXPECT_EQ(cost, parsed);
  }
  arl::CostFunction parsed;
  EXPECT_FALSE(arl::costFunctionFromString("ncc", &parsed));
}

TEST(ImageDifference, RecoversKnownShiftOfARealNordlandFrame)
{
  SKIP_WITHOUT_NORDLAND();
  // The raw 64 x 32 frame shifted right by d px (edge replicated, no wrap), both preprocessed with the
  // default parameters (eq. 1, 8x8 patches): the best shift must be d within half a pixel.
  arl::Preprocessor preprocessor;
  const arl::ImageDifference difference(64, 32, preprocessor.params().skyRows(), 4, true);
  for (int frame : { 1050, 1150, 1250 })
  {
    const cv::Mat raw = nordland::loadFrame("summer", frame);
    ASSERT_FALSE(raw.empty()) << nordland::framePath("summer", frame);
    ASSERT_EQ(64, raw.cols);
    ASSERT_EQ(32, raw.rows);
    cv::Mat keyframe;
    preprocessor.process(raw, arl::PixelFormat::kBgr8, keyframe);
    for (int d : { -3, -1, 2, 3 })
    {
      cv::Mat shifted(raw.size(), raw.type());
      for (int y = 0; y < raw.rows; ++y)
        for (int x = 0; x < raw.cols; ++x)
          shifted.at<cv::Vec3b>(y, x) = raw.at<cv::Vec3b>(y, std::min(63, std::max(0, x - d)));
      cv::Mat query;
      preprocessor.process(shifted, arl::PixelFormat::kBgr8, query);
      const arl::ShiftedDifference best = difference.compare(query.data, keyframe.data);
      EXPECT_NEAR(d, best.shift_px, 0.5) << "frame " << frame << ", d = " << d;
    }
  }
}
