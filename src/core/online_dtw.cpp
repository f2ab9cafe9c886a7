#include "along_route_localization/online_dtw.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include <opencv2/core.hpp>

namespace along_route_localization
{

namespace
{

// Backtracking bytes: bits 0-4 the step k of the (1,k) that led into the state, bits 5-6 the state it
// came from. The state codes start at 1: with a 0 among them GCC does not vectorize updateColumns.
constexpr int kFromShift = 5;
constexpr unsigned char kFromMove = 1, kFromStop = 2, kFromFast = 3;
// Windows at least this wide (a global search) are split into column chunks run by cv::parallel_for_.
constexpr int kParallelMinWidth = 4096;
constexpr int kMinChunkWidth = 2048;

/// The columns [begin, end) of the window [lo, lo + width) that a ring-buffer row computed (its band).
struct BandColumns
{
  int begin, end;
};
BandColumns bandColumns(const CostRingBuffer& buffer, int age, int lo, int width)
{
  const int first = buffer.rowFirst(age);
  const int begin = std::min(std::max(first - lo, 0), width);
  return { begin, std::min(std::max(first + buffer.rowWidth(age) - lo, begin), width) };
}

/// out[j] = the row's cost of keyframe lo + j minus mean[j] for j in [0, width), or `missing` (not
/// centred) outside the row's band.
void centredCosts(const CostRingBuffer& buffer, int age, int lo, int width, float missing, const float* mean,
                  float* out)
{
  const BandColumns band = bandColumns(buffer, age, lo, width);
  const float* row = buffer.row(age);
  const int offset = lo - buffer.rowFirst(age);  // row[j + offset]: keyframe lo + j
  std::fill(out, out + band.begin, missing);
  for (int j = band.begin; j < band.end; ++j)
    out[j] = row[j + offset] - mean[j];
  std::fill(out + band.end, out + width, missing);
}

/// One row of the three states (online_dtw.h): the previous row's, the current row's, and the
/// backtracking bytes (null when not backtracking).
struct StateRows
{
  const float* prev_move;
  const float* prev_stop;
  const float* prev_fast;
  float* cur_move;
  float* cur_stop;
  float* cur_fast;
  unsigned char* move_steps;
  unsigned char* stop_steps;
  unsigned char* fast_steps;
};

/// Columns [from, to) of one row of the recurrence in online_dtw.h, each with `steps` columns to its left:
/// cur_* from prev_* and the centred costs, plus the step bytes with kSteps. S > 0 fixes steps at compile
/// time, so the loop over k unrolls and the loop over j vectorizes. The ternaries are the strict-< chain
/// of the scalar form: a later candidate wins only if strictly smaller (order M, S, F; k ascending).
template <int S, bool kSteps>
#if defined(__GNUC__)
__attribute__((noinline))
#endif
void updateColumns(const DtwParams& params, const float* __restrict prev_move, const float* __restrict prev_stop,
                   const float* __restrict prev_fast, const float* __restrict cost, int from, int to, int steps,
                   float* __restrict cur_move, float* __restrict cur_stop, float* __restrict cur_fast,
                   unsigned char* __restrict move_steps, unsigned char* __restrict stop_steps,
                   unsigned char* __restrict fast_steps)
{
  // The pointers are restrict parameters of a function that is not inlined (not locals copied from
  // StateRows): inlined, GCC loses them and versions the loop over j for aliasing, and runs it unvectorized.
  const int s = S > 0 ? S : steps;
  const float inf = std::numeric_limits<float>::infinity();
  const float stop_penalty = params.stop_penalty, first_stop_penalty = params.first_stop_penalty;
  const float move_penalty = params.move_penalty;
  float speed_up[17], keep_fast[17];
  for (int k = 2; k <= s; ++k)
  {
    speed_up[k] = static_cast<float>(k - 1) * params.skip_penalty;
    keep_fast[k] = static_cast<float>(k - 1) * params.sustained_skip_penalty;
  }
  for (int j = from; j < to; ++j)
  {
    // S: (1,0) after a move (either speed) costs first_stop_penalty, after a stop stop_penalty.
    float best_stop = prev_move[j] + first_stop_penalty;
    int from_stop = kFromMove;
    const float stop_after_fast = prev_fast[j] + first_stop_penalty;
    from_stop = stop_after_fast < best_stop ? kFromFast : from_stop;
    best_stop = stop_after_fast < best_stop ? stop_after_fast : best_stop;
    const float stop_after_stop = prev_stop[j] + stop_penalty;
    from_stop = stop_after_stop < best_stop ? kFromStop : from_stop;
    best_stop = stop_after_stop < best_stop ? stop_after_stop : best_stop;
    cur_stop[j] = cost[j] + best_stop;
    // M: (1,1), free after a stop, move_penalty after a move or a skip.
    float best_move = inf;
    int from_move = kFromMove;
    if (S > 0 || s >= 1)  // always, but in column 0 (updated alone, with s = j = 0)
    {
      best_move = prev_move[j - 1] + move_penalty;
      const float move_after_stop = prev_stop[j - 1];
      from_move = move_after_stop < best_move ? kFromStop : from_move;
      best_move = move_after_stop < best_move ? move_after_stop : best_move;
      const float move_after_fast = prev_fast[j - 1] + move_penalty;
      from_move = move_after_fast < best_move ? kFromFast : from_move;
      best_move = move_after_fast < best_move ? move_after_fast : best_move;
    }
    cur_move[j] = cost[j] + best_move;
    // F: (1,k), k = 2..s: skip_penalty per keyframe skipped when speeding up (from M or S),
    // sustained_skip_penalty when the previous step skipped too.
    float best_fast = inf;
    int choice = 2 | (kFromMove << kFromShift);  // as wide as a float, so the selections vectorize
    const auto fast_step = [&](int k) {
      const float fast_after_move = prev_move[j - k] + speed_up[k];
      choice = fast_after_move < best_fast ? (k | (kFromMove << kFromShift)) : choice;
      best_fast = fast_after_move < best_fast ? fast_after_move : best_fast;
      const float fast_after_stop = prev_stop[j - k] + speed_up[k];
      choice = fast_after_stop < best_fast ? (k | (kFromStop << kFromShift)) : choice;
      best_fast = fast_after_stop < best_fast ? fast_after_stop : best_fast;
      const float fast_after_fast = prev_fast[j - k] + keep_fast[k];
      choice = fast_after_fast < best_fast ? (k | (kFromFast << kFromShift)) : choice;
      best_fast = fast_after_fast < best_fast ? fast_after_fast : best_fast;
    };
    if (S > 0)
    {
      // Written out for the compile-time s, so the loop over j has no inner loop left to vectorize.
      if (S >= 2)
        fast_step(2);
      if (S >= 3)
        fast_step(3);
      if (S >= 4)
        fast_step(4);
    }
    else
    {
      for (int k = 2; k <= s; ++k)
        fast_step(k);
    }
    cur_fast[j] = cost[j] + best_fast;
    if (kSteps)
    {
      stop_steps[j] = static_cast<unsigned char>(from_stop << kFromShift);
      move_steps[j] = static_cast<unsigned char>(1 | (from_move << kFromShift));
      fast_steps[j] = static_cast<unsigned char>(choice);
    }
  }
}

/// Columns [from, to) of one row (step bytes when rows.move_steps is set); column j has min(j, s) to its left.
template <int S, bool kSteps>
void updateRow(const DtwParams& params, const StateRows& rows, const float* cost, int from, int to)
{
  const int s = params.max_step;
  int j = from;
  for (; j < std::min(s, to); ++j)
    updateColumns<0, kSteps>(params, rows.prev_move, rows.prev_stop, rows.prev_fast, cost, j, j + 1, j, rows.cur_move,
                             rows.cur_stop, rows.cur_fast, rows.move_steps, rows.stop_steps, rows.fast_steps);
  updateColumns<S, kSteps>(params, rows.prev_move, rows.prev_stop, rows.prev_fast, cost, j, to, s, rows.cur_move,
                           rows.cur_stop, rows.cur_fast, rows.move_steps, rows.stop_steps, rows.fast_steps);
}

template <int S>
void updateRow(const DtwParams& params, const StateRows& rows, const float* cost, int from, int to)
{
  if (rows.move_steps)
    updateRow<S, true>(params, rows, cost, from, to);
  else
    updateRow<S, false>(params, rows, cost, from, to);
}

/// updateRow with max_step fixed at compile time for the usual values.
void updateRow(const DtwParams& params, const StateRows& rows, const float* cost, int from, int to)
{
  switch (params.max_step)
  {
    case 1:
      return updateRow<1>(params, rows, cost, from, to);
    case 2:
      return updateRow<2>(params, rows, cost, from, to);
    case 3:
      return updateRow<3>(params, rows, cost, from, to);
    case 4:
      return updateRow<4>(params, rows, cost, from, to);
    default:
      return updateRow<0>(params, rows, cost, from, to);
  }
}

}  // namespace

DtwParams cruiseSpeedTieBreak(const DtwParams& params, double cruise_speed)
{
  const double a = std::min(1.0, std::max(0.0, (cruise_speed - 0.5) / 0.5));
  DtwParams out = params;
  out.first_stop_penalty = static_cast<float>(a * params.first_stop_penalty);
  out.move_penalty = static_cast<float>((1.0 - a) * params.first_stop_penalty);
  return out;
}

OnlineDtw::OnlineDtw(const DtwParams& params)
{
  setParams(params);
}

void OnlineDtw::setParams(const DtwParams& params)
{
  if (params.max_step < 1 || params.max_step > 16)
    throw std::invalid_argument("DtwParams: max_step must be in [1, 16]");
  if (params.exclusion_radius < 0)
    throw std::invalid_argument("DtwParams: exclusion_radius must be >= 0");
  params_ = params;
}

void OnlineDtw::accumulateColumns(const CostRingBuffer& buffer, const Window& window, int begin, int end,
                                  Columns& scratch)
{
  // A path ending in [begin, end) only visits columns >= begin - (rows - 1) * s: start there (cells left
  // of `begin` are computed but not kept, and are right wherever such a path can pass).
  const int start = std::max(0, begin - (window.rows - 1) * params_.max_step);
  const int width = end - start, own = begin - start, lo = window.lo + start;
  const float missing = params_.missing_cost;
  scratch.prev_move.resize(width);
  scratch.prev_stop.resize(width);
  scratch.prev_fast.resize(width);
  scratch.cur_move.resize(width);
  scratch.cur_stop.resize(width);
  scratch.cur_fast.resize(width);
  scratch.costs.resize(width);
  scratch.mean.assign(width, 0.0f);
  float* mean = scratch.mean.data();
  if (params_.column_centering && window.rows > 1)
  {
    // Rows of a repeated query carry no new evidence about which keyframes resemble every query: the
    // mean runs over the distinct rows and shrinks by (distinct - 1) / (rows - 1), so a window of one
    // view repeated K times is not centred to zero everywhere. A column's mean is over the rows that
    // computed it, and missing_cost is not centred: averaged in, it made the few computed costs of a
    // keyframe that had just entered the tracking band look cheap, which pulled paths to the band's
    // leading edge.
    scratch.count.assign(width, 0.0f);
    float* count = scratch.count.data();
    int distinct = 0;
    for (int age = 0; age < window.rows; ++age)
    {
      if (!buffer.newView(age, window.rows))
        continue;
      ++distinct;
      const BandColumns band = bandColumns(buffer, age, lo, width);
      const float* row = buffer.row(age);
      const int offset = lo - buffer.rowFirst(age);
      for (int j = band.begin; j < band.end; ++j)
      {
        mean[j] += row[j + offset];
        count[j] += 1.0f;
      }
    }
    const float shrink = static_cast<float>(distinct - 1) / static_cast<float>(window.rows - 1);
    for (int j = 0; j < width; ++j)
      mean[j] = count[j] > 0.0f ? mean[j] * shrink / count[j] : 0.0f;
  }

  // The oldest row: a path starts in state M.
  float* prev_move = scratch.prev_move.data();
  centredCosts(buffer, window.rows - 1, lo, width, missing, mean, prev_move);
  if (window.path_start >= 0)
  {
    for (int j = 0; j < width; ++j)
      if (lo + j != window.path_start)
        prev_move[j] = std::numeric_limits<float>::infinity();
  }
  std::fill(scratch.prev_stop.begin(), scratch.prev_stop.end(), std::numeric_limits<float>::infinity());
  std::fill(scratch.prev_fast.begin(), scratch.prev_fast.end(), std::numeric_limits<float>::infinity());
  float* costs = scratch.costs.data();
  for (int age = window.rows - 2, r = 1; age >= 0; --age, ++r)
  {
    centredCosts(buffer, age, lo, width, missing, mean, costs);
    StateRows rows{ scratch.prev_move.data(), scratch.prev_stop.data(), scratch.prev_fast.data(),
                    scratch.cur_move.data(),  scratch.cur_stop.data(),  scratch.cur_fast.data(),
                    nullptr,                  nullptr,                  nullptr };
    // Columns left of `own` belong to the previous chunk: no step bytes.
    updateRow(params_, rows, costs, 0, own);
    if (window.backtrack)  // indexed by the chunk's column j
    {
      const size_t offset = static_cast<size_t>(r) * window.width + start;
      rows.move_steps = move_steps_.data() + offset;
      rows.stop_steps = stop_steps_.data() + offset;
      rows.fast_steps = fast_steps_.data() + offset;
    }
    updateRow(params_, rows, costs, own, width);
    scratch.prev_move.swap(scratch.cur_move);
    scratch.prev_stop.swap(scratch.cur_stop);
    scratch.prev_fast.swap(scratch.cur_fast);
  }
  std::copy(scratch.prev_move.begin() + own, scratch.prev_move.end(), final_move_.begin() + begin);
  std::copy(scratch.prev_stop.begin() + own, scratch.prev_stop.end(), final_stop_.begin() + begin);
  std::copy(scratch.prev_fast.begin() + own, scratch.prev_fast.end(), final_fast_.begin() + begin);
}

SequenceMatch OnlineDtw::match(const CostRingBuffer& buffer, int first_end, int count, int rows, bool backtrack,
                               const int* keyframe_run, int first_choice, int last_choice, const EndPrior& prior,
                               int path_start)
{
  SequenceMatch result;
  Window window;
  window.rows = std::min(rows, buffer.size());
  if (window.rows <= 0 || count <= 0)
    return result;
  const int num_rows = window.rows;
  // Older rows only matter where a path ending in [first_end, first_end + count) can have been.
  window.lo = std::max(0, first_end - (num_rows - 1) * params_.max_step);
  window.width = first_end + count - window.lo;
  window.backtrack = backtrack;
  window.path_start = path_start;
  const int width = window.width;
  final_move_.resize(width);
  final_stop_.resize(width);
  final_fast_.resize(width);
  if (backtrack)
  {
    move_steps_.resize(static_cast<size_t>(num_rows) * width);
    stop_steps_.resize(static_cast<size_t>(num_rows) * width);
    fast_steps_.resize(static_cast<size_t>(num_rows) * width);
  }

  // Two chunks per thread, so a thread slowed by other work does not hold up the rest.
  const int chunks = parallel_ && width >= kParallelMinWidth ?
                         std::max(1, std::min(2 * cv::getNumThreads(), width / kMinChunkWidth)) :
                         1;
  last_chunks_ = chunks;
  if (static_cast<int>(columns_.size()) < chunks)
    columns_.resize(chunks);  // only grows: shrinking would free the chunks' buffers
  const auto run = [&](const cv::Range& range) {
    for (int c = range.start; c < range.end; ++c)
      accumulateColumns(buffer, window, static_cast<int>(static_cast<int64_t>(width) * c / chunks),
                        static_cast<int>(static_cast<int64_t>(width) * (c + 1) / chunks), columns_[c]);
  };
  if (chunks > 1)
    cv::parallel_for_(cv::Range(0, chunks), run, chunks);
  else
    run(cv::Range(0, 1));

  const float inf = std::numeric_limits<float>::infinity();
  const int end_offset = first_end - window.lo;
  const float norm = 1.0f / static_cast<float>(num_rows);
  last_row_.resize(count);
  for (int i = 0; i < count; ++i)
    last_row_[i] =
        std::min(final_move_[end_offset + i], std::min(final_stop_[end_offset + i], final_fast_[end_offset + i])) *
        norm;
  const int choice_begin = std::min(count - 1, std::max(0, first_choice - first_end));
  const int choice_end = static_cast<int>(std::max<int64_t>(
      choice_begin + 1, std::min<int64_t>(count, static_cast<int64_t>(last_choice) - first_end + 1)));
  int best = choice_begin;
  float best_score = inf;
  for (int i = choice_begin; i < choice_end; ++i)
  {
    float score = last_row_[i];
    const double away = first_end + i - prior.center;
    if (prior.weight > 0.0f && (away > 0.0 || !prior.ahead_only))
      score += prior.weight * std::min(static_cast<float>(std::abs(away)), prior.cap);
    if (score < best_score)
    {
      best_score = score;
      best = i;
    }
  }
  result.keyframe = first_end + best;
  result.cost = last_row_[best];
  result.rows = num_rows;
  result.second_cost = inf;
  result.second_place_cost = inf;
  for (int i = 0; i < count; ++i)
  {
    if (std::abs(i - best) > params_.exclusion_radius && last_row_[i] < result.second_cost)
    {
      result.second_cost = last_row_[i];
      result.has_second = true;
    }
    const int runs_apart = keyframe_run ? std::abs(keyframe_run[first_end + i] - keyframe_run[first_end + best]) :
                                          std::abs(i - best);
    if (runs_apart > params_.exclusion_radius && last_row_[i] < result.second_place_cost)
    {
      result.second_place_cost = last_row_[i];
      result.has_second_place = true;
    }
  }
  if (!result.has_second)
    result.second_cost = result.cost;
  if (!result.has_second_place)
    result.second_place_cost = result.cost;

  if (backtrack)
  {
    result.path.assign(num_rows, 0);
    int j = best + end_offset;
    // The cheapest state at the end, ties in the order M, S, F (as in updateColumns).
    unsigned char state = kFromMove;
    float best_state = final_move_[j];
    if (final_stop_[j] < best_state)
    {
      state = kFromStop;
      best_state = final_stop_[j];
    }
    if (final_fast_[j] < best_state)
      state = kFromFast;
    for (int r = num_rows - 1; r >= 0; --r)
    {
      result.path[r] = window.lo + j;
      if (r == 0)
        break;
      const std::vector<unsigned char>& steps =
          state == kFromStop ? stop_steps_ : (state == kFromFast ? fast_steps_ : move_steps_);
      const unsigned char choice = steps[static_cast<size_t>(r) * width + j];
      j -= choice & 0x1f;  // k = 0 in a stop's byte
      state = static_cast<unsigned char>((choice >> kFromShift) & 0x3);
    }
  }
  return result;
}

}  // namespace along_route_localization
