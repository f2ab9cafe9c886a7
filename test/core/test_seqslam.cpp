// Baseline (seqslam.h): causal straight-line search over the ring buffer.
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/cost_ring_buffer.h"
#include "along_route_localization/seqslam.h"

namespace arl = along_route_localization;

namespace
{

// Appends one full-width row per age, oldest (largest age) first, so that costs[age] ends at that age.
void appendByAge(arl::CostRingBuffer& buffer, const std::vector<std::vector<float>>& costs_by_age)
{
  for (int age = static_cast<int>(costs_by_age.size()) - 1; age >= 0; --age)
  {
    const std::vector<float>& costs = costs_by_age[age];
    float* row = buffer.appendRow(0, static_cast<int>(costs.size()));
    for (size_t j = 0; j < costs.size(); ++j)
      row[j] = costs[j];
  }
}

}  // namespace

TEST(SeqSlam, FindsStraightDiagonalAtVelocityOne)
{
  // 15 rows x 30 keyframes. Ages 0..9 are ones except the diagonal C_age(20 - age) = 0, with 0.2 at
  // ages 3 and 7. Ages 10..14 are 5 everywhere: with ds = 10 they must not count.
  // End 20, v = 1: mean of 0 x 8 + 0.2 x 2 = 0.4 / 10 = 0.04.
  // No end farther than 5 from 20 meets the diagonal within 10 ages for v in [0.8, 1.25]
  // (e.g. end 26 would need 0.25 * age = 6, age 24) -> second cost 1.
  std::vector<std::vector<float>> costs(15, std::vector<float>(30, 1.0f));
  for (int age = 10; age < 15; ++age)
    costs[age].assign(30, 5.0f);
  for (int age = 0; age < 10; ++age)
    costs[age][20 - age] = (age == 3 || age == 7) ? 0.2f : 0.0f;
  arl::CostRingBuffer buffer(15, 30);
  appendByAge(buffer, costs);

  arl::SeqSlamParams params;  // ds 10, v in [0.8, 1.25] step 0.05, missing 1, radius 5
  const arl::SequenceMatch match = arl::seqSlamMatch(buffer, 0, 30, params);
  EXPECT_EQ(20, match.keyframe);
  EXPECT_NEAR(0.04f, match.cost, 1e-6);
  EXPECT_TRUE(match.has_second);
  EXPECT_NEAR(1.0f, match.second_cost, 1e-6);
  EXPECT_EQ(10, match.rows);
}

TEST(SeqSlam, FindsStraightDiagonalAtVelocityHalf)
{
  // Half a keyframe per frame: at age a the trajectory from 20 is at 20 - a/2. For odd a that is
  // x.5, and rounding conventions differ, so both neighbours are 0 there. Only end 20 is 0 at age 0,
  // so the answer is unique: end 20, cost 0, found with v in [0.4, 0.6].
  std::vector<std::vector<float>> costs(10, std::vector<float>(30, 1.0f));
  for (int age = 0; age < 10; ++age)
  {
    costs[age][static_cast<int>(std::floor(20.0 - 0.5 * age))] = 0.0f;
    costs[age][static_cast<int>(std::ceil(20.0 - 0.5 * age))] = 0.0f;
  }
  arl::CostRingBuffer buffer(10, 30);
  appendByAge(buffer, costs);

  arl::SeqSlamParams params;
  params.min_velocity = 0.4f;
  params.max_velocity = 0.6f;
  params.velocity_step = 0.05f;
  const arl::SequenceMatch match = arl::seqSlamMatch(buffer, 0, 30, params);
  EXPECT_EQ(20, match.keyframe);
  EXPECT_NEAR(0.0f, match.cost, 1e-6);

  // Outside the velocity range the straight line cannot follow it: with v >= 0.8 from end 20 the
  // trajectory is at 18 or below by age 8 while the zeros are at 16 -> some ages cost 1.
  const arl::SequenceMatch fast = arl::seqSlamMatch(buffer, 0, 30, arl::SeqSlamParams());
  EXPECT_GT(fast.cost, 0.05f);
}

TEST(SeqSlam, MatchesPlainReferenceAtFixedVelocity)
{
  // v fixed at 1: score(i) = mean over age 0..9 of C_age(i - age), missing (0.7) outside a row's
  // band. Random costs, some rows with narrow bands; argmin and cost from a plain loop.
  const int rows = 12, width = 50, ds = 10;
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> uniform(0.0f, 1.0f);
  arl::CostRingBuffer buffer(rows, width);
  std::vector<int> first(rows), band(rows);
  std::vector<std::vector<float>> values(rows);
  for (int r = 0; r < rows; ++r)  // r = append order; age = rows - 1 - r
  {
    first[r] = (r % 3 == 0) ? 10 : 0;
    band[r] = (r % 3 == 0) ? 25 : width;
    float* row = buffer.appendRow(first[r], band[r]);
    values[r].resize(band[r]);
    for (int j = 0; j < band[r]; ++j)
      row[j] = values[r][j] = uniform(rng);
  }
  auto cost_at = [&](int age, int keyframe) {
    const int r = rows - 1 - age;
    const int offset = keyframe - first[r];
    return (offset >= 0 && offset < band[r]) ? values[r][offset] : 0.7f;
  };
  int best = -1;
  double best_score = 1e9;
  for (int i = 0; i < width; ++i)
  {
    double score = 0.0;
    for (int age = 0; age < ds; ++age)
      score += cost_at(age, i - age);
    score /= ds;
    if (score < best_score)
    {
      best_score = score;
      best = i;
    }
  }
  arl::SeqSlamParams params;
  params.sequence_length = ds;
  params.min_velocity = 1.0f;
  params.max_velocity = 1.0f;
  params.missing_cost = 0.7f;
  const arl::SequenceMatch match = arl::seqSlamMatch(buffer, 0, width, params);
  EXPECT_EQ(best, match.keyframe);
  EXPECT_NEAR(best_score, match.cost, 1e-5);
}
