// Step 4 (online_dtw.h): accumulated cost, backtracked path and the match on hand-made cost matrices.
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "along_route_localization/cost_ring_buffer.h"
#include "along_route_localization/online_dtw.h"

namespace arl = along_route_localization;

namespace
{

// Appends the rows of `matrix` (oldest first), each covering keyframes [0, width).
void appendRows(arl::CostRingBuffer& buffer, const std::vector<std::vector<float>>& matrix)
{
  for (const auto& costs : matrix)
  {
    float* row = buffer.appendRow(0, static_cast<int>(costs.size()));
    for (size_t j = 0; j < costs.size(); ++j)
      row[j] = costs[j];
  }
}

// As appendRows, with repeated_query[r] given to appendRow for row r.
void appendFlaggedRows(arl::CostRingBuffer& buffer, const std::vector<std::vector<float>>& matrix,
                       const std::vector<bool>& repeated_query)
{
  for (size_t r = 0; r < matrix.size(); ++r)
  {
    float* row = buffer.appendRow(0, static_cast<int>(matrix[r].size()), repeated_query[r]);
    for (size_t j = 0; j < matrix[r].size(); ++j)
      row[j] = matrix[r][j];
  }
}

// Ones everywhere, zeros at (row, path[row]).
std::vector<std::vector<float>> onesWithZeroPath(int width, const std::vector<int>& path)
{
  std::vector<std::vector<float>> matrix(path.size(), std::vector<float>(width, 1.0f));
  for (size_t r = 0; r < path.size(); ++r)
    matrix[r][path[r]] = 0.0f;
  return matrix;
}

arl::DtwParams handParams(int exclusion_radius)
{
  arl::DtwParams params;
  params.max_step = 2;
  params.stop_penalty = 0.3f;
  params.skip_penalty = 0.05f;
  params.sustained_skip_penalty = 0.05f;  // every skip pays the same: the plain two-state recursion
  params.first_stop_penalty = 0.0f;       // a stop after a move is free
  params.missing_cost = 1.0f;
  params.exclusion_radius = exclusion_radius;
  params.column_centering = false;  // these tests check the plain recursion; centering has its own test
  return params;
}

// 4 rows over 30 keyframes, ones elsewhere: path A = 0 1 2 3 (zeros) and path B = 17 18 19 20 (zeros, but
// 0.5 in the newest row).
std::vector<std::vector<float>> twoPaths()
{
  std::vector<std::vector<float>> matrix(4, std::vector<float>(30, 1.0f));
  for (int r = 0; r < 4; ++r)
  {
    matrix[r][r] = 0.0f;
    matrix[r][17 + r] = r == 3 ? 0.5f : 0.0f;
  }
  return matrix;
}

// 4 frames x 6 keyframes, ones except zeros at row 0: {0}, row 1: {0, 1}, row 2: {1, 2}, row 3: {2, 3}
// (a station: consecutive frames look like two consecutive keyframes, so every speed from half to one
// keyframe per frame fits).
std::vector<std::vector<float>> stationMatrix()
{
  std::vector<std::vector<float>> matrix(4, std::vector<float>(6, 1.0f));
  matrix[0][0] = 0.0f;
  matrix[1][0] = matrix[1][1] = 0.0f;
  matrix[2][1] = matrix[2][2] = 0.0f;
  matrix[3][2] = matrix[3][3] = 0.0f;
  return matrix;
}

// 8 frames over 10 keyframes: 0 1 2 2 (stop) 3 5 7 (double speed) 8.
const std::vector<int> kStopAndGo = { 0, 1, 2, 2, 3, 5, 7, 8 };

}  // namespace

TEST(OnlineDtw, FollowsStopAndGo)
{
  // The only all-zero path is the one laid out. Its stop 2 -> 2 follows a move, so it is free; it pays
  // only the two (1,2) steps (1 * 0.05 each): 0.1 in total, 0.1 / 8 rows = 0.0125 per row. Every other
  // path crosses a 1.
  arl::CostRingBuffer buffer(8, 10);
  appendRows(buffer, onesWithZeroPath(10, kStopAndGo));
  arl::OnlineDtw dtw(handParams(2));
  const arl::SequenceMatch match = dtw.match(buffer, 0, 10, 8, true);
  EXPECT_EQ(8, match.keyframe);
  EXPECT_NEAR(0.1f / 8, match.cost, 1e-6);
  EXPECT_EQ(8, match.rows);
  ASSERT_EQ(kStopAndGo.size(), match.path.size());
  for (size_t r = 0; r < kStopAndGo.size(); ++r)
    EXPECT_EQ(kStopAndGo[r], match.path[r]) << "row " << r;
}

TEST(OnlineDtw, SustainedSkipsPayTheSustainedPenalty)
{
  // The stop-and-go path has two (1,2) steps in a row (3 -> 5 -> 7). With skip_penalty 0.05 and
  // sustained_skip_penalty 0 only the first pays: 0.05 in total instead of 0.1 (FollowsStopAndGo); the
  // path is unchanged. With skip_penalty 1 and sustained 0, speeding up costs 1 and keeping the speed
  // nothing: 1 / 8; a (1,2) right after a stop or a (1,1) pays the full penalty again.
  arl::CostRingBuffer buffer(8, 10);
  appendRows(buffer, onesWithZeroPath(10, kStopAndGo));
  arl::DtwParams params = handParams(2);
  params.sustained_skip_penalty = 0.0f;
  arl::OnlineDtw dtw(params);
  arl::SequenceMatch match = dtw.match(buffer, 0, 10, 8, true);
  EXPECT_EQ(8, match.keyframe);
  EXPECT_NEAR(0.05f / 8, match.cost, 1e-6);
  EXPECT_EQ(kStopAndGo, match.path);

  params.skip_penalty = 1.0f;
  dtw.setParams(params);
  match = dtw.match(buffer, 0, 10, 8, true);
  EXPECT_EQ(8, match.keyframe);
  EXPECT_NEAR(1.0f / 8, match.cost, 1e-6);
  EXPECT_EQ(kStopAndGo, match.path);

  // 0 2 4 6 | 6 (stop) | 8 10 12: the speed-up after the stop pays again. Costs: ones off the path.
  const std::vector<int> fast_stop_fast = { 0, 2, 4, 6, 6, 8, 10, 12 };
  arl::CostRingBuffer second(8, 14);
  appendRows(second, onesWithZeroPath(14, fast_stop_fast));
  params.first_stop_penalty = 0.0f;
  dtw.setParams(params);
  match = dtw.match(second, 0, 14, 8, true);
  EXPECT_EQ(12, match.keyframe);
  EXPECT_NEAR(2.0f / 8, match.cost, 1e-6);  // two speed-ups (rows 1 and 5), every other step free
  EXPECT_EQ(fast_stop_fast, match.path);
}

TEST(OnlineDtw, AccumulatedRowMatchesHandRecursion)
{
  // A_7(i) = min(M_7(i), S_7(i)), divided by 8, from the recursion of the header (worked by hand and
  // checked with a plain loop outside the code). A stop is free after a move, 0.3 after a stop.
  //   A_7(0) = park on 0 from row 0: 7 ones + 6 repeated stops (the first is free) = 7 + 1.8 = 8.8
  //   A_7(1) = 0 1 (zeros), then park: 6 ones + 5 * 0.3 = 7.5
  //   A_7(2) = the zero path to 2 2 at row 3 (its stop is the free one), then 4 stops on ones, each
  //            after a stop: 4 + 4 * 0.3 = 5.2
  //   A_7(3) = the zero path to 3 at row 4, then 3 stops on ones: 3 + 2 * 0.3 = 3.6
  //   A_7(4) = the zero path to 3 at row 4, then stop, (1,1), stop on ones, both stops free: 3.0
  //   A_7(5) = the zero path to 5 at row 5 (0.05), then 2 stops on ones: 0.05 + 2 + 0.3 = 2.35
  //   A_7(6) = 1 + M_6(6) = 1 + (1 + A_5(5)) = 1 + 1 + 0.05 = 2.05
  //   A_7(7) = 1 + M_6(7) = 1 + 0.1 = 1.1 (one free stop on a one after the zero at row 6)
  //   A_7(8) = 0.1 (FollowsStopAndGo)
  //   A_7(9) = 1 + A_6(7) + 0.05 = 1 + 0.1 + 0.05 = 1.15
  arl::CostRingBuffer buffer(8, 10);
  appendRows(buffer, onesWithZeroPath(10, kStopAndGo));
  arl::OnlineDtw dtw(handParams(2));
  dtw.match(buffer, 0, 10, 8, false);
  const float expected[10] = { 8.8f / 8, 7.5f / 8, 5.2f / 8, 3.6f / 8, 3.0f / 8,
                               2.35f / 8, 2.05f / 8, 1.1f / 8, 0.1f / 8, 1.15f / 8 };
  const std::vector<float>& accumulated = dtw.lastAccumulated();
  ASSERT_EQ(10u, accumulated.size());
  for (int i = 0; i < 10; ++i)
    EXPECT_NEAR(expected[i], accumulated[i], 1e-5) << "keyframe " << i;
}

namespace
{

// Blocks of `hand` (rows x block columns) laid every block + 16 columns across an 8200-column window of
// cost 1000, starting `phase` columns in: the offsets of the blocks. No step (1,s), s <= 3, gets over the
// 16 columns of 1000 between blocks, so no path from outside a block is cheaper than the block's own.
std::vector<int> layBlocks(const std::vector<std::vector<float>>& hand, int phase, int width,
                           arl::CostRingBuffer* buffer)
{
  const int block = static_cast<int>(hand[0].size()), padding = 16;
  std::vector<std::vector<float>> matrix(hand.size(), std::vector<float>(width, 1000.0f));
  std::vector<int> offsets;
  for (int offset = phase + padding; offset + block <= width; offset += block + padding)
  {
    offsets.push_back(offset);
    for (size_t r = 0; r < matrix.size(); ++r)
      std::copy(hand[r].begin(), hand[r].end(), matrix[r].begin() + offset);
  }
  appendRows(*buffer, matrix);
  return offsets;
}

// For each block at `offsets`: the path to its column `end`, chosen alone, is `path` (block columns).
void expectPathsToBlockEnds(arl::OnlineDtw& dtw, const arl::CostRingBuffer& buffer, int width,
                            const std::vector<int>& offsets, int end, const std::vector<int>& path,
                            const std::string& context)
{
  for (int offset : offsets)
  {
    const arl::SequenceMatch match = dtw.match(buffer, 0, width, static_cast<int>(path.size()), true, nullptr,
                                               offset + end, offset + end);
    ASSERT_EQ(offset + end, match.keyframe) << context << ", block at " << offset;
    ASSERT_EQ(path.size(), match.path.size()) << context;
    for (size_t r = 0; r < path.size(); ++r)
      ASSERT_EQ(offset + path[r], match.path[r]) << context << ", block at " << offset << ", row " << r;
  }
}

}  // namespace

TEST(OnlineDtw, WideWindowsSplitIntoParallelChunksGiveTheHandRecursion)
{
  // A window of 4096 columns or more (a global search) is split into column chunks, run on several
  // threads; a chunk starts its recursion (rows - 1) x s columns before its first column. Blocks of
  // hand-worked costs are laid across such a window (layBlocks), shifted one column at a time over a
  // whole period, so every chunk boundary falls at every position inside a block:
  //  - AccumulatedRowMatchesHandRecursion's 8 x 10 matrix (s = 2): each block's accumulated row is the
  //    hand one, and the path to its end 8, chosen alone, is kStopAndGo (stops, moves and skips);
  //  - zeros on 0, s, 2s ... 7s (ones elsewhere, 8 x (7s + 1)), s = 2 and 3: the only path that reaches
  //    column 7s in 8 rows takes seven (1,s) steps from column 0, each paying (s - 1) x 0.05, and is the
  //    path to that end. A chunk that starts its recursion even one column late does not have it.
  const float expected[10] = { 8.8f / 8, 7.5f / 8, 5.2f / 8, 3.6f / 8, 3.0f / 8,
                               2.35f / 8, 2.05f / 8, 1.1f / 8, 0.1f / 8, 1.15f / 8 };
  const int width = 8200;
  arl::OnlineDtw dtw(handParams(2));
  for (int phase = 0; phase < 10 + 16; ++phase)
  {
    arl::CostRingBuffer buffer(8, width);
    const std::vector<int> offsets = layBlocks(onesWithZeroPath(10, kStopAndGo), phase, width, &buffer);
    for (bool backtrack : { false, true })
    {
      dtw.match(buffer, 0, width, 8, backtrack);
      ASSERT_GT(dtw.lastChunks(), 1) << "the window was not split";
      const std::vector<float> accumulated = dtw.lastAccumulated();
      ASSERT_EQ(static_cast<size_t>(width), accumulated.size());
      for (int offset : offsets)
        for (int i = 0; i < 10; ++i)
          ASSERT_NEAR(expected[i], accumulated[offset + i], 1e-5)
              << "phase " << phase << ", block at " << offset << ", keyframe " << i << ", backtrack " << backtrack;
    }
    expectPathsToBlockEnds(dtw, buffer, width, offsets, 8, kStopAndGo, "phase " + std::to_string(phase));
    if (HasFatalFailure())
      return;
  }
  for (int step : { 2, 3 })
  {
    arl::DtwParams params = handParams(2);
    params.max_step = step;
    dtw.setParams(params);
    std::vector<int> diagonal;
    for (int r = 0; r < 8; ++r)
      diagonal.push_back(step * r);
    const int end = diagonal.back();
    for (int phase = 0; phase < end + 1 + 16; ++phase)
    {
      arl::CostRingBuffer buffer(8, width);
      const std::vector<int> offsets = layBlocks(onesWithZeroPath(end + 1, diagonal), phase, width, &buffer);
      dtw.match(buffer, 0, width, 8, false);
      ASSERT_GT(dtw.lastChunks(), 1) << "the window was not split";
      const std::vector<float> accumulated = dtw.lastAccumulated();
      for (int offset : offsets)
        ASSERT_NEAR(7 * (step - 1) * 0.05f / 8, accumulated[offset + end], 1e-6)
            << "s " << step << ", phase " << phase << ", block at " << offset;
      expectPathsToBlockEnds(dtw, buffer, width, offsets, end, diagonal,
                             "s " + std::to_string(step) + ", phase " + std::to_string(phase));
      if (HasFatalFailure())
        return;
    }
  }
}

TEST(OnlineDtw, WideWindowsGiveTheSameInParallelChunksAsInOnePiece)
{
  // Random costs, the default step costs and column centering: split into chunks (setParallel(true), the
  // default) or in one piece (setParallel(false)), the accumulated row, the match, its margins and its
  // path are the same bit for bit (every cell is computed by the same operations either way).
  const int width = 9000, rows = 10;
  arl::CostRingBuffer buffer(rows, width);
  unsigned state = 12345;
  for (int r = 0; r < rows; ++r)
  {
    float* row = buffer.appendRow(0, width, r == 4);
    for (int j = 0; j < width; ++j)
    {
      state = state * 1103515245u + 12345u;
      row[j] = static_cast<float>((state >> 8) % 1000) / 500.0f;
    }
  }
  arl::OnlineDtw chunked, whole;
  whole.setParallel(false);
  for (int used_rows : { rows, 3 })
  {
    const arl::SequenceMatch a = chunked.match(buffer, 0, width, used_rows, true);
    const arl::SequenceMatch b = whole.match(buffer, 0, width, used_rows, true);
    EXPECT_GT(chunked.lastChunks(), 1);
    EXPECT_EQ(1, whole.lastChunks());
    EXPECT_EQ(b.keyframe, a.keyframe);
    EXPECT_EQ(b.cost, a.cost);
    EXPECT_EQ(b.second_cost, a.second_cost);
    EXPECT_EQ(b.path, a.path);
    ASSERT_EQ(whole.lastAccumulated().size(), chunked.lastAccumulated().size());
    for (int j = 0; j < width; ++j)
      ASSERT_EQ(whole.lastAccumulated()[j], chunked.lastAccumulated()[j]) << "keyframe " << j << ", rows " << used_rows;
  }
}

TEST(OnlineDtw, APathStartFixesWhereEveryPathBegins)
{
  // twoPaths: A = 0 1 2 3 (zeros), B = 17 18 19 20 (zeros, 0.5 in the newest row). Free to start
  // anywhere, A wins at cost 0. Every path starting at keyframe 17: B wins, 0.5 / 4 rows; ends left of
  // 17 cannot be reached (paths only go forward) and neither can those past 17 + 3 rows * s = 23.
  // End 23 takes three (1,2) steps over ones: 3 + 0.05 * 3 = 3.15, / 4.
  arl::CostRingBuffer buffer(4, 30);
  appendRows(buffer, twoPaths());
  arl::OnlineDtw dtw(handParams(2));
  arl::SequenceMatch match = dtw.match(buffer, 0, 30, 4, true);
  EXPECT_EQ(3, match.keyframe);
  EXPECT_NEAR(0.0f, match.cost, 1e-6);

  // All ends 0..29, and ends 15..29 only: there the window's older rows start at keyframe 15 - 3 * 2 = 9,
  // not 0, and the start is still keyframe 17 (not the window's column 17).
  for (const int first_end : { 0, 15 })
  {
    const int count = 30 - first_end;
    match = dtw.match(buffer, first_end, count, 4, true, nullptr, 0, std::numeric_limits<int>::max(),
                      arl::EndPrior(), 17);
    EXPECT_EQ(20, match.keyframe) << "ends from " << first_end;
    EXPECT_NEAR(0.5f / 4, match.cost, 1e-6) << "ends from " << first_end;
    EXPECT_EQ((std::vector<int>{ 17, 18, 19, 20 }), match.path) << "ends from " << first_end;
    const std::vector<float>& accumulated = dtw.lastAccumulated();
    for (int i = 0; i < count; ++i)
    {
      const int k = first_end + i;
      EXPECT_EQ(k >= 17 && k <= 23, std::isfinite(accumulated[i])) << "keyframe " << k;
    }
    EXPECT_NEAR(3.15f / 4, accumulated[23 - first_end], 1e-5);
    // The competition is among the paths from 17 too: the best end farther than 2 from 20 is 23.
    ASSERT_TRUE(match.has_second);
    EXPECT_NEAR(3.15f / 4, match.second_cost, 1e-5);
  }

  // Starting where A starts changes nothing for A.
  match = dtw.match(buffer, 0, 30, 4, true, nullptr, 0, std::numeric_limits<int>::max(), arl::EndPrior(), 0);
  EXPECT_EQ(3, match.keyframe);
  EXPECT_NEAR(0.0f, match.cost, 1e-6);
}

TEST(OnlineDtw, SecondCostRespectsExclusionRadius)
{
  // Best end 8 (A = 0.1). Others (AccumulatedRowMatchesHandRecursion): A_7(9) = 1.15, A_7(7) = 1.1,
  // A_7(6) = 2.05, A_7(5) = 2.35, A_7(4) = 3.0, A_7(0..3) larger.
  // radius 0 -> best outside {8} is keyframe 7 (1.1 < 1.15): 1.1 / 8; radius 1 -> outside [7, 9]:
  // keyframe 6, 2.05 / 8; radius 2 -> outside [6, 10]: keyframe 5, 2.35 / 8; radius 9 -> nothing left.
  arl::CostRingBuffer buffer(8, 10);
  appendRows(buffer, onesWithZeroPath(10, kStopAndGo));
  const float expected[3] = { 1.1f / 8, 2.05f / 8, 2.35f / 8 };
  for (int radius = 0; radius < 3; ++radius)
  {
    arl::OnlineDtw dtw(handParams(radius));
    const arl::SequenceMatch match = dtw.match(buffer, 0, 10, 8);
    EXPECT_EQ(8, match.keyframe);
    EXPECT_TRUE(match.has_second) << "radius " << radius;
    EXPECT_NEAR(expected[radius], match.second_cost, 1e-5) << "radius " << radius;
  }
  arl::OnlineDtw wide(handParams(9));
  EXPECT_FALSE(wide.match(buffer, 0, 10, 8).has_second);
}

TEST(OnlineDtw, FirstChoiceLimitsTheMatchNotTheCompetition)
{
  // Two paths over 4 rows of 30 keyframes, ones elsewhere: A = 0 1 2 3 (all zeros, total 0) and
  // B = 17 18 19 20 (zeros, but 0.5 at row 3, total 0.5). Unrestricted the match is A's end, 3, with
  // B's end as the runner-up: 0.5 / 4. With first_choice 10 the match is B's end, 20 (0.5 / 4), and A's
  // cheaper end still competes: second_cost 0 / 4, i.e. no margin.
  arl::CostRingBuffer buffer(4, 30);
  appendRows(buffer, twoPaths());
  arl::OnlineDtw dtw(handParams(5));
  const arl::SequenceMatch free_match = dtw.match(buffer, 0, 30, 4, true);
  EXPECT_EQ(3, free_match.keyframe);
  EXPECT_NEAR(0.0f, free_match.cost, 1e-6);
  EXPECT_NEAR(0.5f / 4, free_match.second_cost, 1e-6);

  const arl::SequenceMatch limited = dtw.match(buffer, 0, 30, 4, true, nullptr, 10);
  EXPECT_EQ(20, limited.keyframe);
  EXPECT_NEAR(0.5f / 4, limited.cost, 1e-6);
  ASSERT_TRUE(limited.has_second);
  EXPECT_NEAR(0.0f, limited.second_cost, 1e-6);
  EXPECT_NEAR(0.0f, limited.second_place_cost, 1e-6);
  EXPECT_EQ((std::vector<int>{ 17, 18, 19, 20 }), limited.path);
  // last_choice limits the other side: in [10, 19] the cheapest end is 19, one step short of B's (a
  // path with one (1,0) or one 1 more); with [0, 2] it is 2, next to A's.
  const arl::SequenceMatch before_b = dtw.match(buffer, 0, 30, 4, false, nullptr, 10, 19);
  EXPECT_EQ(19, before_b.keyframe);
  EXPECT_NEAR(0.0f, before_b.second_cost, 1e-6);
  EXPECT_EQ(2, dtw.match(buffer, 0, 30, 4, false, nullptr, 0, 2).keyframe);
  // A first_choice before the window or past its end clamps to it.
  EXPECT_EQ(3, dtw.match(buffer, 0, 30, 4, false, nullptr, -7).keyframe);
  EXPECT_EQ(29, dtw.match(buffer, 0, 30, 4, false, nullptr, 99).keyframe);
}

TEST(OnlineDtw, UsesOnlyTheNewestRows)
{
  // rows = 3: only frames 5..7 (keyframes 5, 7, 8) count: one (1,2) step -> 0.05 / 3.
  // rows = 20 > size: all 8 rows, as in FollowsStopAndGo: one free stop and two (1,2) steps -> 0.1 / 8.
  arl::CostRingBuffer buffer(8, 10);
  appendRows(buffer, onesWithZeroPath(10, kStopAndGo));
  arl::OnlineDtw dtw(handParams(2));
  const arl::SequenceMatch three = dtw.match(buffer, 0, 10, 3, true);
  EXPECT_EQ(8, three.keyframe);
  EXPECT_EQ(3, three.rows);
  EXPECT_NEAR(0.05f / 3, three.cost, 1e-6);
  ASSERT_EQ(3u, three.path.size());
  EXPECT_EQ(5, three.path[0]);
  EXPECT_EQ(7, three.path[1]);
  EXPECT_EQ(8, three.path[2]);
  const arl::SequenceMatch all = dtw.match(buffer, 0, 10, 20, true);
  EXPECT_EQ(8, all.rows);
  EXPECT_NEAR(0.1f / 8, all.cost, 1e-6);
}

TEST(OnlineDtw, StopPenaltyKeepsThePathFromParking)
{
  // 6 frames x 10 keyframes: keyframe 2 costs 0 in every row (a featureless keyframe under plain SAD),
  // the true diagonal 3..8 costs 0.1 per row, the rest 1.
  // stop 0.3: parking on 2 makes 5 stops; the first follows the start and is free, the other 4 each
  // follow a stop: 4 * 0.3 = 1.2 (A_5(2), nothing reaches 2 cheaper). The best path starts on keyframe
  // 2 (0), steps (1,2) to 4 (0.05 + 0.1) and follows the diagonal to 8 (4 * 0.1): 0.55 < 1.2
  // -> end 8, 0.55 / 6.
  // stop 0: parking on 2 costs nothing and wins -> end 2, cost 0.
  std::vector<std::vector<float>> matrix(6, std::vector<float>(10, 1.0f));
  for (int r = 0; r < 6; ++r)
  {
    matrix[r][2] = 0.0f;
    matrix[r][r + 3] = 0.1f;
  }
  arl::CostRingBuffer buffer(6, 10);
  appendRows(buffer, matrix);
  arl::OnlineDtw with_penalty(handParams(2));
  const arl::SequenceMatch moving = with_penalty.match(buffer, 0, 10, 6, true);
  EXPECT_EQ(8, moving.keyframe);
  EXPECT_NEAR(0.55f / 6, moving.cost, 1e-6);
  EXPECT_NEAR(1.2f / 6, with_penalty.lastAccumulated()[2], 1e-5);  // the parked path
  ASSERT_EQ(6u, moving.path.size());
  const int expected_path[6] = { 2, 4, 5, 6, 7, 8 };
  for (int r = 0; r < 6; ++r)
    EXPECT_EQ(expected_path[r], moving.path[r]) << "row " << r;

  arl::DtwParams free_stop = handParams(2);
  free_stop.stop_penalty = 0.0f;
  arl::OnlineDtw parking(free_stop);
  const arl::SequenceMatch parked = parking.match(buffer, 0, 10, 6);
  EXPECT_EQ(2, parked.keyframe);
  EXPECT_NEAR(0.0f, parked.cost, 1e-6);
}

TEST(OnlineDtw, MatchCanLeaveTheStepRangeAndRecover)
{
  // K = 8, 40 keyframes. First 8 frames on the diagonal 0..7 -> match 7. Then 5 frames at keyframes
  // 30..34 (a relocation no (1,k) step can follow). The buffer now holds frames at 5, 6, 7 and 30..34.
  // Continuing the old path costs 5 ones (5); the new path crosses 3 ones in the old rows and then
  // zeros (3): end 34, far outside [7, 7 + s], cost 3 / 8 = 0.375.
  // A single stop is free, so in the old rows (all ones where the new path can be) five paths tie at
  // 3 + 0 penalty: 27 28 29, 28 28 29, 28 29 29, 28 29 30 and 29 29 30 (the last two then stop on 30
  // at row 3, again free); every other start pays a repeated stop or a skip. The header does not say
  // which tied path backtracking returns, so rows 0..2 must be one of these five; rows 3..7 are 30..34.
  arl::CostRingBuffer buffer(8, 40);
  appendRows(buffer, onesWithZeroPath(40, { 0, 1, 2, 3, 4, 5, 6, 7 }));
  arl::OnlineDtw dtw(handParams(5));
  const arl::SequenceMatch before = dtw.match(buffer, 0, 40, 8);
  EXPECT_EQ(7, before.keyframe);
  EXPECT_NEAR(0.0f, before.cost, 1e-6);

  std::vector<std::vector<float>> jump(5, std::vector<float>(40, 1.0f));
  for (int r = 0; r < 5; ++r)
    jump[r][30 + r] = 0.0f;
  appendRows(buffer, jump);
  const arl::SequenceMatch after = dtw.match(buffer, 0, 40, 8, true);
  EXPECT_EQ(34, after.keyframe);
  EXPECT_NEAR(0.375f, after.cost, 1e-6);
  ASSERT_EQ(8u, after.path.size());
  const std::vector<std::vector<int>> tied = { { 27, 28, 29 }, { 28, 28, 29 }, { 28, 29, 29 },
                                               { 28, 29, 30 }, { 29, 29, 30 } };
  const std::vector<int> old_rows(after.path.begin(), after.path.begin() + 3);
  EXPECT_NE(tied.end(), std::find(tied.begin(), tied.end(), old_rows))
      << "rows 0..2: " << old_rows[0] << " " << old_rows[1] << " " << old_rows[2];
  for (int r = 3; r < 8; ++r)
    EXPECT_EQ(27 + r, after.path[r]) << "row " << r;
}

TEST(OnlineDtw, MissingCostIsUsedOutsideTheBands)
{
  // Row 0: [0, 10) all 0.5. Row 1: band [2, 5) = 0 0 0. Row 2: band [3, 6) = 0.2 0.1 0.3.
  // M_0 = 0.5 everywhere. missing 1: row 1 costs 1 0 0 0 1 ... (keyframes 0..9); a step from row 0 is
  // a free stop or a move, so M_1(i) = S_1(i) = C_1(i) + 0.5 (M_1(0) = inf): A_1(i) = 0.5 for i in
  // 2..4, 1.5 elsewhere. S_1(0) = 1.5 is the only way to stay on 0.
  // A_2(4) = 0.1 + A_1(3) = 0.6 (best), A_2(3) = 0.2 + A_1(2) = 0.7, A_2(5) = 0.3 + A_1(4) = 0.8,
  // A_2(6) = 1 + A_1(4) + 0.05 = 1.55, A_2(0) = 1 + S_1(0) + 0.3 = 2.8 (the second stop on 0 pays),
  // A_2(1) = 1 + 1.5 = 2.5 (0 0 1 or 0 1 1, one free stop; 1 1 1 would pay 0.3).
  // missing 5: S_1(0) = 5.5, A_2(0) = 5 + 5.5 + 0.3 = 10.8; A_2(6) = 5 + A_1(4) + 0.05 = 5.55.
  arl::CostRingBuffer buffer(3, 10);
  float* row0 = buffer.appendRow(0, 10);
  for (int j = 0; j < 10; ++j)
    row0[j] = 0.5f;
  float* row1 = buffer.appendRow(2, 3);
  row1[0] = row1[1] = row1[2] = 0.0f;
  float* row2 = buffer.appendRow(3, 3);
  row2[0] = 0.2f;
  row2[1] = 0.1f;
  row2[2] = 0.3f;

  arl::OnlineDtw dtw(handParams(2));
  const arl::SequenceMatch match = dtw.match(buffer, 0, 10, 3);
  EXPECT_EQ(4, match.keyframe);
  EXPECT_NEAR(0.6f / 3, match.cost, 1e-6);
  ASSERT_EQ(10u, dtw.lastAccumulated().size());
  EXPECT_NEAR(2.8f / 3, dtw.lastAccumulated()[0], 1e-5);
  EXPECT_NEAR(2.5f / 3, dtw.lastAccumulated()[1], 1e-5);
  EXPECT_NEAR(0.7f / 3, dtw.lastAccumulated()[3], 1e-5);
  EXPECT_NEAR(0.8f / 3, dtw.lastAccumulated()[5], 1e-5);
  EXPECT_NEAR(1.55f / 3, dtw.lastAccumulated()[6], 1e-5);

  arl::DtwParams expensive = handParams(2);
  expensive.missing_cost = 5.0f;
  dtw.setParams(expensive);
  EXPECT_EQ(4, dtw.match(buffer, 0, 10, 3).keyframe);
  EXPECT_NEAR(10.8f / 3, dtw.lastAccumulated()[0], 1e-5);
  EXPECT_NEAR(5.55f / 3, dtw.lastAccumulated()[6], 1e-5);
}

TEST(OnlineDtw, MaxStepLimitsTheSpeed)
{
  // 4 frames at keyframes 0, 3, 6, 9 (three keyframes per frame). With s = 3 the zero path is
  // reachable at 2 * 0.05 per (1,3) step, no stops: 3 * 0.1 = 0.3 -> end 9, 0.3 / 4. With s = 2 no two
  // zeros are linked by a step of at most 2, so every path crosses at least 3 ones: cost >= 3 / 4
  // (reached exactly, e.g. by 0 0 1 1: two single stops, both free).
  arl::CostRingBuffer buffer(4, 12);
  appendRows(buffer, onesWithZeroPath(12, { 0, 3, 6, 9 }));
  arl::DtwParams fast = handParams(2);
  fast.max_step = 3;
  arl::OnlineDtw dtw(fast);
  const arl::SequenceMatch match = dtw.match(buffer, 0, 12, 4, true);
  EXPECT_EQ(9, match.keyframe);
  EXPECT_NEAR(0.3f / 4, match.cost, 1e-6);
  ASSERT_EQ(4u, match.path.size());
  EXPECT_EQ(3, match.path[1]);
  EXPECT_EQ(6, match.path[2]);

  arl::OnlineDtw slow(handParams(2));
  const arl::SequenceMatch limited = slow.match(buffer, 0, 12, 4);
  EXPECT_GE(limited.cost, 3.0f / 4 - 1e-6f);
}

TEST(OnlineDtw, ColumnCenteringStopsAGenericKeyframeFromCarryingThePath)
{
  // 3 frames x 4 keyframes. Keyframe 0 costs 0.15 in every row (a view that resembles every query);
  // the diagonal 1, 2, 3 costs 0.3 per row, the rest 1. stop 0.3, skip 0.05.
  // Plain: parking on 0 costs 3 * 0.15 + 0.3 (second stop) = 0.75 < diagonal 0.9 -> end 0, 0.75 / 3.
  // Centred: column means 0.15 and (0.3 + 1 + 1) / 3; keyframe 0 becomes 0 per row (parking 0.3),
  // the diagonal 3 * (0.3 - 2.3 / 3) = -1.4 -> end 3, cost -1.4 / 3.
  arl::CostRingBuffer buffer(3, 4);
  appendRows(buffer, { { 0.15f, 0.3f, 1.0f, 1.0f }, { 0.15f, 1.0f, 0.3f, 1.0f }, { 0.15f, 1.0f, 1.0f, 0.3f } });
  arl::OnlineDtw plain(handParams(0));
  const arl::SequenceMatch parked = plain.match(buffer, 0, 4, 3);
  EXPECT_EQ(0, parked.keyframe);
  EXPECT_NEAR(0.75f / 3, parked.cost, 1e-6);

  arl::DtwParams centred_params = handParams(0);
  centred_params.column_centering = true;
  arl::OnlineDtw centred(centred_params);
  const arl::SequenceMatch moving = centred.match(buffer, 0, 4, 3, true);
  EXPECT_EQ(3, moving.keyframe);
  EXPECT_NEAR(-1.4f / 3, moving.cost, 1e-5);
  ASSERT_EQ(3u, moving.path.size());
  EXPECT_EQ(1, moving.path[0]);
  EXPECT_EQ(2, moving.path[1]);
  EXPECT_EQ(3, moving.path[2]);
}

TEST(OnlineDtw, FirstStopPenaltyBreaksTiesTowardsNominalSpeed)
{
  // stationMatrix(). stop 0.3, skip 0.05.
  // first_stop_penalty 0:
  //   A_3(3) = 0: 0 1 2 3, one keyframe per frame, all zeros, no stop.
  //   A_3(2) = 0: 0 0 1 2 (or 0 1 1 2, 0 1 2 2), all zeros, one stop after a move: free.
  //   A_3(1) = 1: 0 0 1 1, zeros then the 1 at (3, 1), both stops follow a move: free.
  //   A_3(0) = 2.6: 0 0 0 0, ones at rows 2 and 3, the first stop free, the other two 0.3 each.
  //   A tie between ends 2 and 3; the argmin takes the first minimum in keyframe order: end 2, the
  //   path that stopped.
  // first_stop_penalty 0.05 (every stop after a move now pays it):
  //   A_3(3) = 0 (no stop on 0 1 2 3); A_3(2) = 0 + 0.05 (every path to 2 in 3 rows stops at least once,
  //   and the zero ones stop once): the nominal path is cheaper by exactly the penalty -> end 3, 0 / 4.
  //   A_3(1) = 1 + 0.05 + 0.05 = 1.1 (0 0 1 1: two first stops; 0 1 1 1 = 1 + 0.05 + 0.3 = 1.35).
  //   A_3(0) = 2 + 0.05 + 0.3 + 0.3 = 2.65 (only the first of the three stops follows a move).
  arl::CostRingBuffer buffer(4, 6);
  appendRows(buffer, stationMatrix());

  arl::OnlineDtw free_first_stop(handParams(1));
  const arl::SequenceMatch tied = free_first_stop.match(buffer, 0, 6, 4);
  const std::vector<float>& tied_row = free_first_stop.lastAccumulated();
  ASSERT_EQ(6u, tied_row.size());
  EXPECT_NEAR(0.0f, tied_row[2], 1e-6);
  EXPECT_NEAR(0.0f, tied_row[3], 1e-6);
  EXPECT_NEAR(1.0f / 4, tied_row[1], 1e-6);
  EXPECT_NEAR(2.6f / 4, tied_row[0], 1e-6);
  EXPECT_EQ(2, tied.keyframe);
  EXPECT_NEAR(0.0f, tied.cost, 1e-6);

  arl::DtwParams params = handParams(1);
  params.first_stop_penalty = 0.05f;
  arl::OnlineDtw nominal(params);
  const arl::SequenceMatch match = nominal.match(buffer, 0, 6, 4, true);
  const std::vector<float>& row = nominal.lastAccumulated();
  ASSERT_EQ(6u, row.size());
  EXPECT_EQ(3, match.keyframe);
  EXPECT_NEAR(0.0f, match.cost, 1e-6);
  EXPECT_NEAR(0.05f / 4, row[2], 1e-6);
  EXPECT_NEAR(0.05f / 4, row[2] - row[3], 1e-6);
  EXPECT_NEAR(1.1f / 4, row[1], 1e-6);
  EXPECT_NEAR(2.65f / 4, row[0], 1e-6);
  ASSERT_EQ(4u, match.path.size());
  for (int r = 0; r < 4; ++r)
    EXPECT_EQ(r, match.path[r]) << "row " << r;
}

TEST(OnlineDtw, CruiseSpeedTieBreakSharesTheFirstStopPenaltyWithStraightMoves)
{
  arl::DtwParams nominal = handParams(1);
  nominal.first_stop_penalty = 0.05f;
  for (const double speed : { 1.0, 1.7 })
  {
    const arl::DtwParams same = arl::cruiseSpeedTieBreak(nominal, speed);
    EXPECT_FLOAT_EQ(0.05f, same.first_stop_penalty) << speed;
    EXPECT_FLOAT_EQ(0.0f, same.move_penalty) << speed;
  }
  const arl::DtwParams between = arl::cruiseSpeedTieBreak(nominal, 0.75);  // a = 0.5
  EXPECT_FLOAT_EQ(0.025f, between.first_stop_penalty);
  EXPECT_FLOAT_EQ(0.025f, between.move_penalty);
  for (const double speed : { 0.5, 0.2, 0.0 })
  {
    const arl::DtwParams half = arl::cruiseSpeedTieBreak(nominal, speed);
    EXPECT_FLOAT_EQ(0.0f, half.first_stop_penalty) << speed;
    EXPECT_FLOAT_EQ(0.05f, half.move_penalty) << speed;
    EXPECT_FLOAT_EQ(nominal.stop_penalty, half.stop_penalty);
    EXPECT_FLOAT_EQ(nominal.skip_penalty, half.skip_penalty);
  }
}

TEST(OnlineDtw, AtHalfCruiseSpeedTheTieGoesToTheStopThatAlternatesWithMoves)
{
  // stationMatrix() (rows 1-3 fit two consecutive keyframes each), with skips at 1 so that only stops and moves compete, and the step costs of
  // cruiseSpeedTieBreak(first_stop_penalty 0.05, cruise speed 0.5): a stop after a move is free, a (1,1)
  // after a (1,1) pays 0.05 (the oldest row starts as a move). stop 0.3.
  //   A_3(3) = 0.15: 0 1 2 3, three moves after moves (0 0 1 3 would skip: 1).
  //   A_3(2) = 0.05: 0 0 1 2 (free stop, free move after a stop, then a move after a move) or 0 1 1 2.
  //   A_3(1) = 1: 0 0 1 1 (all steps free, the 1 at (3, 1)).
  //   A_3(0) = 2.6: 0 0 0 0 (ones at rows 2 and 3, the second and third stops 0.3 each).
  // -> end 2, half a keyframe per frame; at the nominal speed's costs the same matrix ends at 3.
  arl::CostRingBuffer buffer(4, 6);
  appendRows(buffer, stationMatrix());
  arl::DtwParams nominal = handParams(1);
  nominal.first_stop_penalty = 0.05f;
  nominal.skip_penalty = nominal.sustained_skip_penalty = 1.0f;

  arl::OnlineDtw half(arl::cruiseSpeedTieBreak(nominal, 0.5));
  const arl::SequenceMatch match = half.match(buffer, 0, 6, 4, true);
  const std::vector<float>& row = half.lastAccumulated();
  ASSERT_EQ(6u, row.size());
  EXPECT_NEAR(0.15f / 4, row[3], 1e-6);
  EXPECT_NEAR(0.05f / 4, row[2], 1e-6);
  EXPECT_NEAR(1.0f / 4, row[1], 1e-6);
  EXPECT_NEAR(2.6f / 4, row[0], 1e-6);
  EXPECT_EQ(2, match.keyframe);
  ASSERT_EQ(4u, match.path.size());
  EXPECT_EQ(2, match.path[3]);
  EXPECT_EQ(1, match.path[2]);

  arl::OnlineDtw full(arl::cruiseSpeedTieBreak(nominal, 1.0));
  EXPECT_EQ(3, full.match(buffer, 0, 6, 4).keyframe);
}

TEST(OnlineDtw, RepeatedRowsAreLeftOutOfTheColumnMean)
{
  // stop 0.3, skip 0.05, column centering on.
  arl::DtwParams params = handParams(1);
  params.column_centering = true;

  // (a) K' = 3 rows of one view C = 0.4 0.1 0.6 0.3, all flagged repeatedQuery (the oldest too: it
  // repeats a frame that has left the window; the oldest always counts as distinct). D = 1: scale
  // (1 - 1) / (3 - 1) = 0, no centring, so A_2 is the plain recursion:
  //   A_2(0) = 3 * 0.4 + 0.3 (the second stop)            = 1.5
  //   A_2(1) = 0 1 1: 0.4 + 0.1 + 0.1 (one free stop)      = 0.6
  //   A_2(2) = 1 1 2: 0.1 + 0.1 + 0.6                      = 0.8
  //   A_2(3) = 1 1 3: 0.1 + 0.1 + 0.3 + 0.05 (one (1,2))   = 0.55 (best)
  // Without the flags every column would be centred to 0: A_2 = 0.3 (0 0 0, one paid stop), 0, 0, 0.
  {
    const std::vector<std::vector<float>> same(3, { 0.4f, 0.1f, 0.6f, 0.3f });
    arl::CostRingBuffer buffer(3, 4);
    appendFlaggedRows(buffer, same, { true, true, true });
    arl::OnlineDtw dtw(params);
    const arl::SequenceMatch match = dtw.match(buffer, 0, 4, 3);
    const float expected[4] = { 1.5f / 3, 0.6f / 3, 0.8f / 3, 0.55f / 3 };
    ASSERT_EQ(4u, dtw.lastAccumulated().size());
    for (int i = 0; i < 4; ++i)
      EXPECT_NEAR(expected[i], dtw.lastAccumulated()[i], 1e-6) << "keyframe " << i;
    EXPECT_EQ(3, match.keyframe);
    EXPECT_NEAR(0.55f / 3, match.cost, 1e-6);
    // The plain recursion on the same buffer gives the same row.
    arl::OnlineDtw plain(handParams(1));
    plain.match(buffer, 0, 4, 3);
    for (int i = 0; i < 4; ++i)
      EXPECT_NEAR(plain.lastAccumulated()[i], dtw.lastAccumulated()[i], 1e-6) << "keyframe " << i;

    arl::CostRingBuffer unflagged(3, 4);
    appendFlaggedRows(unflagged, same, { false, false, false });
    dtw.match(unflagged, 0, 4, 3);
    const float flat[4] = { 0.3f / 3, 0.0f, 0.0f, 0.0f };
    for (int i = 0; i < 4; ++i)
      EXPECT_NEAR(flat[i], dtw.lastAccumulated()[i], 1e-6) << "keyframe " << i;
  }

  // (b) K' = 4 rows X X X Y, oldest first, X = 0.1 0.4 1.0 0.7 and Y = 0.5 0.2 0.2 0.5, flags
  // T T T F: the oldest X counts, the two repeats of X do not, so D = 2 distinct rows (X, Y).
  // mean = (X + Y) / 2 * (2 - 1) / (4 - 1) = (0.6 0.6 1.2 1.2) / 6 = 0.1 0.1 0.2 0.2
  // X' = X - mean = 0 0.3 0.8 0.5, Y' = Y - mean = 0.4 0.1 0 0.3.
  //   A_3(0) = 0 0 0 0: 0 + 0 + 0 + 0.4 + 0.3 + 0.3 (first stop free)            = 1.0
  //   A_3(1) = 0 0 1 1: 0 + 0 + 0.3 + 0.1, both stops after a move (0 0 0 1 ties) = 0.4
  //   A_3(2) = 0 0 1 2: 0 + 0 + 0.3 + 0 (one free stop)                        = 0.3 (best)
  //   A_3(3) = 0 0 1 3: 0 + 0 + 0.3 + 0.3 + 0.05 (one (1,2))                   = 0.65
  // The plain mean over all 4 rows, (3X + Y) / 4 = 0.2 0.35 0.8 0.65 (no flags), would give
  // A_3(2) = -0.1 - 0.1 + 0.05 - 0.6 = -0.75 instead.
  {
    const std::vector<float> x = { 0.1f, 0.4f, 1.0f, 0.7f };
    const std::vector<float> y = { 0.5f, 0.2f, 0.2f, 0.5f };
    arl::CostRingBuffer buffer(4, 4);
    appendFlaggedRows(buffer, { x, x, x, y }, { true, true, true, false });
    arl::OnlineDtw dtw(params);
    const arl::SequenceMatch match = dtw.match(buffer, 0, 4, 4, true);
    const float expected[4] = { 1.0f / 4, 0.4f / 4, 0.3f / 4, 0.65f / 4 };
    ASSERT_EQ(4u, dtw.lastAccumulated().size());
    for (int i = 0; i < 4; ++i)
      EXPECT_NEAR(expected[i], dtw.lastAccumulated()[i], 1e-6) << "keyframe " << i;
    EXPECT_EQ(2, match.keyframe);
    EXPECT_NEAR(0.3f / 4, match.cost, 1e-6);
    ASSERT_EQ(4u, match.path.size());
    const int expected_path[4] = { 0, 0, 1, 2 };
    for (int r = 0; r < 4; ++r)
      EXPECT_EQ(expected_path[r], match.path[r]) << "row " << r;

    arl::CostRingBuffer unflagged(4, 4);
    appendFlaggedRows(unflagged, { x, x, x, y }, { false, false, false, false });
    dtw.match(unflagged, 0, 4, 4);
    EXPECT_NEAR(-0.75f / 4, dtw.lastAccumulated()[2], 1e-6);
  }
}

TEST(OnlineDtw, ColumnMeansLeaveOutRowsThatDidNotComputeTheKeyframe)
{
  // While tracking, keyframes enter the band at its leading edge: keyframe 3 below is computed by the
  // newest row only (missing 1 in the two older rows). Rows, oldest first, bands [0, 3), [0, 3), [0, 4):
  //   0 1 1 | 1 0 1 | 1 1 0 -0.2.  stop 0.3, skip 0.05, column centering on.
  // Means over the rows that computed the column: 2/3 for keyframes 0-2, -0.2 for keyframe 3.
  // Centred: diagonal -2/3 per row (A(2) = 3 * -2/3 = -2, the match), keyframe 3's newest cost 0,
  // its missing entries stay 1. A(3) = 0 + (0 -> 1 -> then a (1,2) step from keyframe 1: -4/3 + 0.05)
  // = -1.2833. With missing_cost averaged into the mean (1 + 1 - 0.2) / 3 = 0.6, keyframe 3's newest cost
  // would become -0.8 and A(3) = -2.0833 < -2: the band's edge would win.
  arl::DtwParams params = handParams(0);
  params.column_centering = true;
  arl::CostRingBuffer buffer(3, 4);
  appendRows(buffer, { { 0.0f, 1.0f, 1.0f }, { 1.0f, 0.0f, 1.0f }, { 1.0f, 1.0f, 0.0f, -0.2f } });
  arl::OnlineDtw dtw(params);
  const arl::SequenceMatch match = dtw.match(buffer, 0, 4, 3);
  EXPECT_EQ(2, match.keyframe);
  EXPECT_NEAR(-2.0f / 3, match.cost, 1e-6);
  ASSERT_EQ(4u, dtw.lastAccumulated().size());
  EXPECT_NEAR((-4.0f / 3 + 0.05f) / 3, dtw.lastAccumulated()[3], 1e-6);
}

TEST(OnlineDtw, SecondPlaceCostCountsRunsNotKeyframes)
{
  // kStopAndGo again: A_7 = 8.8 7.5 5.2 3.6 3.0 2.35 2.05 1.1 0.1 1.15 (AccumulatedRowMatchesHandRecursion),
  // best end 8. keyframe_run marks keyframes 7, 8, 9 as copies of one view (run 7):
  //   runs = 0 1 2 3 4 5 6 7 7 7.
  // radius 0: second_cost (keyframes != 8) = A(7) = 1.1; second_place_cost (runs != 7, keyframes 0..6)
  //           = A(6) = 2.05.
  // radius 1: second_cost (outside keyframes [7, 9]) = A(6) = 2.05; second_place_cost (runs <= 5,
  //           keyframes 0..5) = A(5) = 2.35.
  // The same with candidates [2, 10) (first_end 2): keyframe_run is indexed by keyframe, not candidate.
  // Without keyframe_run, second_place_cost = second_cost.
  arl::CostRingBuffer buffer(8, 10);
  appendRows(buffer, onesWithZeroPath(10, kStopAndGo));
  const int runs[10] = { 0, 1, 2, 3, 4, 5, 6, 7, 7, 7 };
  const float second[2] = { 1.1f / 8, 2.05f / 8 };
  const float second_place[2] = { 2.05f / 8, 2.35f / 8 };
  for (int radius = 0; radius < 2; ++radius)
  {
    arl::OnlineDtw dtw(handParams(radius));
    for (int first_end : { 0, 2 })
    {
      const arl::SequenceMatch match = dtw.match(buffer, first_end, 10 - first_end, 8, false, runs);
      EXPECT_EQ(8, match.keyframe);
      EXPECT_NEAR(0.1f / 8, match.cost, 1e-6);
      EXPECT_TRUE(match.has_second) << "radius " << radius << " first_end " << first_end;
      EXPECT_NEAR(second[radius], match.second_cost, 1e-6) << "radius " << radius << " first_end " << first_end;
      EXPECT_TRUE(match.has_second_place) << "radius " << radius << " first_end " << first_end;
      EXPECT_NEAR(second_place[radius], match.second_place_cost, 1e-6)
          << "radius " << radius << " first_end " << first_end;
    }
    const arl::SequenceMatch no_runs = dtw.match(buffer, 0, 10, 8);
    EXPECT_TRUE(no_runs.has_second_place) << "radius " << radius;
    EXPECT_NEAR(second[radius], no_runs.second_place_cost, 1e-6) << "radius " << radius;
  }

  // Two runs, keyframes 0..4 and 5..9: with radius 1 every candidate is within one run of run 1, so
  // there is no second place (second_place_cost falls back to cost = 0.1 / 8), while second_cost
  // (keyframes outside [7, 9]) is still A(6) = 2.05.
  const int two_runs[10] = { 0, 0, 0, 0, 0, 1, 1, 1, 1, 1 };
  arl::OnlineDtw dtw(handParams(1));
  const arl::SequenceMatch match = dtw.match(buffer, 0, 10, 8, false, two_runs);
  EXPECT_EQ(8, match.keyframe);
  EXPECT_TRUE(match.has_second);
  EXPECT_NEAR(2.05f / 8, match.second_cost, 1e-6);
  EXPECT_FALSE(match.has_second_place);
  EXPECT_NEAR(0.1f / 8, match.second_place_cost, 1e-6);
  // radius 0: run 0 (keyframes 0..4) counts; its best is A(4) = 3.0.
  arl::OnlineDtw narrow(handParams(0));
  const arl::SequenceMatch narrow_match = narrow.match(buffer, 0, 10, 8, false, two_runs);
  EXPECT_TRUE(narrow_match.has_second_place);
  EXPECT_NEAR(3.0f / 8, narrow_match.second_place_cost, 1e-6);
}

TEST(OnlineDtw, EndPriorBreaksNearTiesButNotStrongEvidence)
{
  // twoPaths, as in FirstChoiceLimitsTheMatchNotTheCompetition: A ends at 3 (cost 0 / 4), B at 20
  // (0.5 / 4 = 0.125); the end 19 next to B costs 1 / 4 (17 18 19 19, the last row off B).
  arl::CostRingBuffer buffer(4, 30);
  appendRows(buffer, twoPaths());
  arl::OnlineDtw dtw(handParams(5));
  arl::EndPrior prior;
  prior.center = 19.0;
  prior.weight = 0.01f;
  // Uncapped: A's end pays 0.01 * 16 = 0.16, B's 0.125 + 0.01 = 0.135, 19's 0.25 + 0: B's end.
  arl::SequenceMatch match = dtw.match(buffer, 0, 30, 4, true, nullptr, 0, 29, prior);
  EXPECT_EQ(20, match.keyframe);
  EXPECT_NEAR(0.125f, match.cost, 1e-6);  // the end's own cost, without the prior
  ASSERT_TRUE(match.has_second);
  EXPECT_NEAR(0.0f, match.second_cost, 1e-6);  // A's cheaper end still competes: no margin
  EXPECT_EQ((std::vector<int>{ 17, 18, 19, 20 }), match.path);
  // Ahead only: A's end, behind the prediction, pays nothing and is the match again.
  prior.ahead_only = true;
  EXPECT_EQ(3, dtw.match(buffer, 0, 30, 4, false, nullptr, 0, 29, prior).keyframe);
  // Ends ahead still pay. Predicted at 1 with weight 0.5: end 1 costs 0.575 (0 1 1 1: 2 + a second stop
  // 0.3, over 4 rows) and pays nothing, end 2 0.25 (0 1 2 2) + 0.5, A's end 3 0 + 1, end 0 0.9 + 0.
  prior.center = 1.0;
  prior.weight = 0.5f;
  EXPECT_EQ(1, dtw.match(buffer, 0, 30, 4, false, nullptr, 0, 29, prior).keyframe);
  prior.center = 19.0;
  prior.weight = 0.01f;
  prior.ahead_only = false;
  // Capped at 2 keyframes, A's end pays 0.02 < 0.135: evidence far from the prediction wins.
  prior.cap = 2.0f;
  EXPECT_EQ(3, dtw.match(buffer, 0, 30, 4, false, nullptr, 0, 29, prior).keyframe);
  // Weight 0: no prior, the cheapest end.
  prior.cap = std::numeric_limits<float>::infinity();
  prior.weight = 0.0f;
  EXPECT_EQ(3, dtw.match(buffer, 0, 30, 4, false, nullptr, 0, 29, prior).keyframe);
  // Predicted at 10, the prior pays 0.07 for A's end and 0.1 for B's: A's (0.07 < 0.225).
  prior.center = 10.0;
  prior.weight = 0.01f;
  EXPECT_EQ(3, dtw.match(buffer, 0, 30, 4, false, nullptr, 0, 29, prior).keyframe);
}
