#include "along_route_localization/online_dtw.h"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace along_route_localization
{

namespace
{

/// Fills `out[j]` with the cost of keyframe lo + j in the row of that age (missing outside its band).
void loadRow(const CostRingBuffer& buffer, int age, int lo, int width, float missing, float* out)
{
  const int first = buffer.rowFirst(age), band = buffer.rowWidth(age);
  const float* row = buffer.row(age);
  for (int j = 0; j < width; ++j)
  {
    const int offset = lo + j - first;
    out[j] = (offset >= 0 && offset < band) ? row[offset] : missing;
  }
}

}  // namespace

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

SequenceMatch OnlineDtw::match(const CostRingBuffer& buffer, int first_end, int count, int rows, bool backtrack,
                                const int* keyframe_run)
{
  SequenceMatch result;
  const int num_rows = std::min(rows, buffer.size());
  if (num_rows <= 0 || count <= 0)
    return result;
  const int s = params_.max_step;
  // Older rows only matter where a path ending in [first_end, first_end + count) can have been.
  const int lo = std::max(0, first_end - (num_rows - 1) * s);
  const int hi = first_end + count;  // exclusive
  const int width = hi - lo;
  const size_t cells = static_cast<size_t>(num_rows) * width;
  prev_move_.resize(width);
  prev_stop_.resize(width);
  cur_move_.resize(width);
  cur_stop_.resize(width);
  costs_.resize(width);
  if (backtrack)
  {
    move_steps_.resize(cells);
    stop_steps_.resize(cells);
  }

  column_mean_.assign(width, 0.0f);
  if (params_.column_centering && num_rows > 1)
  {
    // Rows of a repeated query carry no new evidence about which keyframes resemble every query: the
    // mean runs over the distinct rows and shrinks by (distinct - 1) / (rows - 1), so a window of one
    // view repeated K times is not centred to zero everywhere.
    int distinct = 0;
    for (int age = 0; age < num_rows; ++age)
    {
      if (buffer.repeatedQuery(age) && age != num_rows - 1)
        continue;
      ++distinct;
      loadRow(buffer, age, lo, width, params_.missing_cost, costs_.data());
      for (int j = 0; j < width; ++j)
        column_mean_[j] += costs_[j];
    }
    const float scale = static_cast<float>(distinct - 1) / static_cast<float>(num_rows - 1) / static_cast<float>(distinct);
    for (float& m : column_mean_)
      m *= scale;
  }

  constexpr unsigned char kFromStop = 0x80;
  const float inf = std::numeric_limits<float>::infinity();
  loadRow(buffer, num_rows - 1, lo, width, params_.missing_cost, costs_.data());
  for (int j = 0; j < width; ++j)
  {
    prev_move_[j] = costs_[j] - column_mean_[j];  // a path may start in either state
    prev_stop_[j] = inf;
  }
  for (int age = num_rows - 2, r = 1; age >= 0; --age, ++r)
  {
    loadRow(buffer, age, lo, width, params_.missing_cost, costs_.data());
    unsigned char* move_row = backtrack ? move_steps_.data() + static_cast<size_t>(r) * width : nullptr;
    unsigned char* stop_row = backtrack ? stop_steps_.data() + static_cast<size_t>(r) * width : nullptr;
    for (int j = 0; j < width; ++j)
    {
      const float cost = costs_[j] - column_mean_[j];
      // S: (1,0) after a move is free, after a stop it costs stop_penalty.
      const float after_stop = prev_stop_[j] + params_.stop_penalty;
      const float after_move = prev_move_[j] + params_.first_stop_penalty;
      const bool stop_from_stop = after_stop < after_move;
      cur_stop_[j] = cost + (stop_from_stop ? after_stop : after_move);
      // M: (1,k), k = 1..s, from either state.
      float best = inf;
      unsigned char choice = 1;
      for (int k = 1; k <= s && k <= j; ++k)
      {
        const float penalty = static_cast<float>(k - 1) * params_.skip_penalty;
        if (prev_move_[j - k] + penalty < best)
        {
          best = prev_move_[j - k] + penalty;
          choice = static_cast<unsigned char>(k);
        }
        if (prev_stop_[j - k] + penalty < best)
        {
          best = prev_stop_[j - k] + penalty;
          choice = static_cast<unsigned char>(k | kFromStop);
        }
      }
      cur_move_[j] = cost + best;
      if (backtrack)
      {
        move_row[j] = choice;
        stop_row[j] = stop_from_stop ? kFromStop : 0;
      }
    }
    prev_move_.swap(cur_move_);
    prev_stop_.swap(cur_stop_);
  }

  const int end_offset = first_end - lo;
  const float norm = 1.0f / static_cast<float>(num_rows);
  last_row_.resize(count);
  for (int i = 0; i < count; ++i)
    last_row_[i] = std::min(prev_move_[end_offset + i], prev_stop_[end_offset + i]) * norm;
  const auto best_it = std::min_element(last_row_.begin(), last_row_.end());
  const int best = static_cast<int>(best_it - last_row_.begin());
  result.keyframe = first_end + best;
  result.cost = *best_it;
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
    bool in_stop = prev_stop_[j] < prev_move_[j];
    for (int r = num_rows - 1; r >= 0; --r)
    {
      result.path[r] = lo + j;
      if (r == 0)
        break;
      const unsigned char choice = (in_stop ? stop_steps_ : move_steps_)[static_cast<size_t>(r) * width + j];
      j -= in_stop ? 0 : (choice & 0x1f);
      in_stop = (choice & kFromStop) != 0;
    }
  }
  return result;
}

}  // namespace along_route_localization
