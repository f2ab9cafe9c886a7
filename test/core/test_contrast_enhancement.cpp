// Step 3a (contrast_enhancement.h): eq. 2 on known vectors, worked out by hand, and against a plain
// windowed reference on a long random vector.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/contrast_enhancement.h"

namespace arl = along_route_localization;

namespace
{

std::vector<float> enhance(const std::vector<float>& costs, const std::vector<uint8_t>* informative,
                           int half_window, float min_std, float clamp, float neutral)
{
  std::vector<float> out(costs.size(), -12345.0f);
  arl::enhanceContrast(costs.data(), informative ? informative->data() : nullptr, static_cast<int>(costs.size()),
                       half_window, min_std, clamp, neutral, out.data());
  return out;
}

// eq. 2 written directly from the header: window recomputed from scratch for every entry.
std::vector<double> reference(const std::vector<float>& costs, const std::vector<uint8_t>& informative,
                              int half_window, double min_std, double clamp, double neutral)
{
  const int count = static_cast<int>(costs.size());
  std::vector<double> out(count);
  for (int i = 0; i < count; ++i)
  {
    double sum = 0.0, sum_sq = 0.0;
    int n = 0;
    for (int j = std::max(0, i - half_window); j <= std::min(count - 1, i + half_window); ++j)
      if (informative[j])
      {
        sum += costs[j];
        sum_sq += static_cast<double>(costs[j]) * costs[j];
        ++n;
      }
    if (!informative[i] || n < 2)
    {
      out[i] = neutral;
      continue;
    }
    const double mean = sum / n;
    const double std_dev = std::sqrt(std::max(0.0, sum_sq / n - mean * mean));
    out[i] = std::min(clamp, std::max(-clamp, (costs[i] - mean) / std::max(std_dev, min_std)));
  }
  return out;
}

}  // namespace

TEST(ContrastEnhancement, KnownVectorHalfWindow1)
{
  // D = 1 2 4 8 16, n = 1, windows clipped at the ends:
  // i=0: {1,2} mean 1.5, std 0.5 -> (1 - 1.5) / 0.5 = -1
  // i=1: {1,2,4} mean 7/3, std sqrt(14/9) = 1.2472 -> (2 - 2.3333) / 1.2472 = -0.26726
  // i=2: {2,4,8} = 2 * {1,2,4} -> -0.26726;  i=3: {4,8,16} -> -0.26726
  // i=4: {8,16} mean 12, std 4 -> (16 - 12) / 4 = +1
  const std::vector<float> out = enhance({ 1, 2, 4, 8, 16 }, nullptr, 1, 1e-6f, 100.0f, 0.0f);
  const float expected[] = { -1.0f, -0.267261f, -0.267261f, -0.267261f, 1.0f };
  for (int i = 0; i < 5; ++i)
    EXPECT_NEAR(expected[i], out[i], 1e-4) << "entry " << i;
}

TEST(ContrastEnhancement, KnownVectorHalfWindow2)
{
  // D = 3 1 4 1 5 9 2 6, n = 2:
  // i=0: {3,1,4} mean 8/3, std 1.2472 -> 0.26726
  // i=1: {3,1,4,1} mean 2.25, std sqrt(1.6875) = 1.2990 -> -0.96225
  // i=2: {3,1,4,1,5} mean 2.8, std 1.6 -> 0.75
  // i=3: {1,4,1,5,9} mean 4, std sqrt(8.8) = 2.9665 -> -1.01130
  // i=6: {5,9,2,6} mean 5.5, std 2.5 -> -1.4
  // i=7: {9,2,6} mean 17/3, std 2.8674 -> 0.11625
  const std::vector<float> costs = { 3, 1, 4, 1, 5, 9, 2, 6 };
  const std::vector<float> out = enhance(costs, nullptr, 2, 1e-6f, 100.0f, 0.0f);
  EXPECT_NEAR(0.267261f, out[0], 1e-4);
  EXPECT_NEAR(-0.962250f, out[1], 1e-4);
  EXPECT_NEAR(0.75f, out[2], 1e-4);
  EXPECT_NEAR(-1.011300f, out[3], 1e-4);
  EXPECT_NEAR(-1.4f, out[6], 1e-4);
  EXPECT_NEAR(0.116248f, out[7], 1e-4);
  const std::vector<uint8_t> all(costs.size(), 1);
  const std::vector<double> expected = reference(costs, all, 2, 1e-6, 100.0, 0.0);
  for (size_t i = 0; i < costs.size(); ++i)
    EXPECT_NEAR(expected[i], out[i], 1e-4) << "entry " << i;
}

TEST(ContrastEnhancement, UninformativeEntriesAreNeutralAndLeaveTheStatistics)
{
  // D = 1 2 100 4 8, entry 2 uninformative, n = 1, neutral 0.5:
  // i=2 -> 0.5; i=1: window {1,2} (100 excluded) -> (2 - 1.5) / 0.5 = +1;
  // i=3: {4,8} -> (4 - 6) / 2 = -1; i=0: {1,2} -> -1; i=4: {4,8} -> +1.
  const std::vector<uint8_t> informative = { 1, 1, 0, 1, 1 };
  const std::vector<float> out = enhance({ 1, 2, 100, 4, 8 }, &informative, 1, 1e-6f, 100.0f, 0.5f);
  const float expected[] = { -1.0f, 1.0f, 0.5f, -1.0f, 1.0f };
  for (int i = 0; i < 5; ++i)
    EXPECT_NEAR(expected[i], out[i], 1e-4) << "entry " << i;
}

TEST(ContrastEnhancement, FewerThanTwoInformativeValuesGiveNeutral)
{
  // D = 5 7 9, only entry 0 informative: its window {5} holds one value -> neutral; 1 and 2 are
  // uninformative -> neutral.
  const std::vector<uint8_t> informative = { 1, 0, 0 };
  const std::vector<float> out = enhance({ 5, 7, 9 }, &informative, 1, 1e-6f, 100.0f, 0.25f);
  for (int i = 0; i < 3; ++i)
    EXPECT_FLOAT_EQ(0.25f, out[i]) << "entry " << i;
}

TEST(ContrastEnhancement, MinStdFloorsTheDivisor)
{
  // D = 10 10.1 10, n = 1, min_std 1: i=1 window std 0.0471 < 1 -> (10.1 - 10.0333) / 1 = 0.0667;
  // i=0: {10, 10.1} std 0.05 < 1 -> (10 - 10.05) / 1 = -0.05.
  const std::vector<float> out = enhance({ 10.0f, 10.1f, 10.0f }, nullptr, 1, 1.0f, 100.0f, 0.0f);
  EXPECT_NEAR(-0.05f, out[0], 1e-4);
  EXPECT_NEAR(0.066667f, out[1], 1e-4);
  EXPECT_NEAR(-0.05f, out[2], 1e-4);
  // A flat vector: std 0 -> floor -> 0 everywhere (and no division by zero).
  const std::vector<float> flat = enhance({ 3, 3, 3, 3 }, nullptr, 1, 0.05f, 4.0f, 9.0f);
  for (int i = 0; i < 4; ++i)
    EXPECT_FLOAT_EQ(0.0f, flat[i]) << "entry " << i;
}

TEST(ContrastEnhancement, ResultsAreClamped)
{
  // D = 0 0 0 0 100 0 0 0 0, n = 2: i=4 window {0,0,100,0,0} mean 20, std 40 -> (100-20)/40 = 2 ->
  // clamped to 1.5; i=3 window {0,0,0,100,0} -> (0 - 20) / 40 = -0.5 (inside the clamp).
  const std::vector<float> out = enhance({ 0, 0, 0, 0, 100, 0, 0, 0, 0 }, nullptr, 2, 1e-6f, 1.5f, 0.0f);
  EXPECT_FLOAT_EQ(1.5f, out[4]);
  EXPECT_NEAR(-0.5f, out[3], 1e-5);
  EXPECT_NEAR(-0.5f, out[5], 1e-5);
  // Mirror image: one low value among highs -> -2 -> clamped to -1.5.
  const std::vector<float> low = enhance({ 100, 100, 100, 100, 0, 100, 100, 100, 100 }, nullptr, 2, 1e-6f, 1.5f, 0.0f);
  EXPECT_FLOAT_EQ(-1.5f, low[4]);
}

TEST(ContrastEnhancement, NullInformativeMeansAllInformative)
{
  const std::vector<float> costs = { 4, 8, 15, 16, 23, 42 };
  const std::vector<uint8_t> all(costs.size(), 1);
  const std::vector<float> with_null = enhance(costs, nullptr, 2, 0.05f, 4.0f, 0.0f);
  const std::vector<float> with_ones = enhance(costs, &all, 2, 0.05f, 4.0f, 0.0f);
  for (size_t i = 0; i < costs.size(); ++i)
    EXPECT_FLOAT_EQ(with_ones[i], with_null[i]) << "entry " << i;
}

TEST(ContrastEnhancement, LongRandomVectorMatchesPlainReference)
{
  // Running sums must agree with the window recomputed from scratch, including the clipped ends and
  // a mask with ~15 % uninformative entries. Costs in the range SAD costs take (0..60 gray levels).
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> cost(0.0f, 60.0f);
  std::bernoulli_distribution dark(0.15);
  const int count = 1788;
  std::vector<float> costs(count);
  std::vector<uint8_t> informative(count);
  for (int i = 0; i < count; ++i)
  {
    costs[i] = cost(rng);
    informative[i] = dark(rng) ? 0 : 1;
  }
  for (int half_window : { 1, 10, 40 })
  {
    const std::vector<float> out = enhance(costs, &informative, half_window, 0.05f, 4.0f, 0.0f);
    const std::vector<double> expected = reference(costs, informative, half_window, 0.05, 4.0, 0.0);
    for (int i = 0; i < count; ++i)
      ASSERT_NEAR(expected[i], out[i], 2e-3) << "entry " << i << ", n = " << half_window;
  }
}

TEST(ContrastEnhancement, RunsOfRepeatedKeyframesCountOnce)
{
  // costs 1 1 1 4 0, keyframes 1 and 2 repeat keyframe 0: runs {1}, {4}, {0}; n = 1 run each side.
  // run 0: window {1, 4}: mean 2.5, std 1.5 -> (1 - 2.5) / 1.5 = -1 for entries 0, 1, 2
  // run 1: window {1, 4, 0}: mean 5/3, std sqrt(17/3 - 25/9) = sqrt(26)/3 -> (4 - 5/3) / (sqrt(26)/3) = 7/sqrt(26)
  // run 2: window {4, 0}: mean 2, std 2 -> -1
  const std::vector<float> costs = { 1, 1, 1, 4, 0 };
  const std::vector<uint8_t> repeats = { 0, 1, 1, 0, 0 };
  std::vector<float> out(5);
  arl::ContrastRunsScratch scratch;
  arl::enhanceContrastRuns(costs.data(), nullptr, repeats.data(), 5, 1, 0.01f, 10.0f, 0.0f, out.data(), &scratch);
  EXPECT_NEAR(-1.0f, out[0], 1e-5);
  EXPECT_NEAR(-1.0f, out[1], 1e-5);
  EXPECT_NEAR(-1.0f, out[2], 1e-5);
  EXPECT_NEAR(7.0 / std::sqrt(26.0), out[3], 1e-5);
  EXPECT_NEAR(-1.0f, out[4], 1e-5);
  // Counted per keyframe, the window of entry 1 is {1, 1, 1}: std 0, the true match looks neutral.
  std::vector<float> plain(5);
  arl::enhanceContrast(costs.data(), nullptr, 5, 1, 0.01f, 10.0f, 0.0f, plain.data());
  EXPECT_NEAR(0.0f, plain[1], 1e-5);
  // No repeats: the same as enhanceContrast.
  const std::vector<uint8_t> none(5, 0);
  arl::enhanceContrastRuns(costs.data(), nullptr, none.data(), 5, 1, 0.01f, 10.0f, 0.0f, out.data(), &scratch);
  for (int i = 0; i < 5; ++i)
    EXPECT_NEAR(plain[i], out[i], 1e-5) << i;
}

TEST(ContrastEnhancement, ReturnsHowFarTheBestEntryStandsOutBeforeTheClamp)
{
  // costs 3 3 3 1 3 3 3, one window over all (n = 10): mean 19/7, population variance 55/7 - 361/49 =
  // 24/49, so the 1 scores (1 - 19/7) / (sqrt(24) / 7) = -12 / sqrt(24) = -sqrt(6): clamped to -2 in the
  // output, the peak is sqrt(6).
  const std::vector<float> dip = { 3, 3, 3, 1, 3, 3, 3 };
  std::vector<float> out(7);
  const float peak = arl::enhanceContrast(dip.data(), nullptr, 7, 10, 0.01f, 2.0f, 0.0f, out.data());
  EXPECT_NEAR(std::sqrt(6.0), peak, 1e-5);
  EXPECT_FLOAT_EQ(-2.0f, out[3]);
  // The runs version, without repeats, returns the same.
  arl::ContrastRunsScratch scratch;
  const std::vector<uint8_t> none(7, 0);
  const float runs_peak =
      arl::enhanceContrastRuns(dip.data(), nullptr, none.data(), 7, 10, 0.01f, 2.0f, 0.0f, out.data(), &scratch);
  EXPECT_NEAR(std::sqrt(6.0), runs_peak, 1e-5);
  // Only scores below the mean count: 1 1 1 3 1 1 1 has its largest score (+sqrt(6)) above it, and the
  // ones score (1 - 9/7) / (sqrt(24) / 7) = -2 / sqrt(24), so the peak is 1 / sqrt(6).
  const std::vector<float> bump = { 1, 1, 1, 3, 1, 1, 1 };
  EXPECT_NEAR(1.0 / std::sqrt(6.0), arl::enhanceContrast(bump.data(), nullptr, 7, 10, 0.01f, 2.0f, 0.0f, out.data()),
              1e-5);
  // Uninformative entries are not scored: the dip masked out leaves a flat row, peak 0.
  std::vector<uint8_t> informative(7, 1);
  informative[3] = 0;
  EXPECT_FLOAT_EQ(0.0f, arl::enhanceContrast(dip.data(), informative.data(), 7, 10, 0.01f, 2.0f, 0.0f, out.data()));
}

TEST(ContrastEnhancement, RowWeightIsThePeakOverTheReferenceWithinTheRange)
{
  EXPECT_FLOAT_EQ(1.1f, arl::rowWeight(2.475f, 2.25f, 0.2f));  // 2.475 / 2.25
  EXPECT_FLOAT_EQ(0.8f, arl::rowWeight(0.5f, 2.25f, 0.2f));    // 0.22, raised to 1 - 0.2
  EXPECT_FLOAT_EQ(1.2f, arl::rowWeight(9.0f, 2.25f, 0.2f));    // 4, lowered to 1 + 0.2
  EXPECT_FLOAT_EQ(1.0f, arl::rowWeight(9.0f, 2.25f, 0.0f));    // range 0: every row weighs 1
}
