#include "along_route_localization/homing.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <memory>
#include <sstream>
#include <stdexcept>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/intrin.hpp>

namespace along_route_localization
{

namespace
{

/// sums[i] = sum over `rows` rows (`stride` bytes apart) of |query[i] - keyframe[i]|, i in [0, columns).
void columnSums(const uint8_t* query, const uint8_t* keyframe, size_t stride, int rows, int columns, uint32_t* sums)
{
#if CV_SIMD128
  // 16 columns at a time in 16-bit lanes (255 * 257 fits); a last, partial block overlaps the one before.
  if (columns >= 16 && rows <= 257)
  {
    for (int done = 0; done < columns; done += 16)
    {
      const int start = std::min(done, columns - 16);
      cv::v_uint16x8 low = cv::v_setzero_u16(), high = cv::v_setzero_u16();
      const uint8_t* q = query + start;
      const uint8_t* k = keyframe + start;
      for (int y = 0; y < rows; ++y, q += stride, k += stride)
      {
        cv::v_uint16x8 a, b;
        cv::v_expand(cv::v_absdiff(cv::v_load(q), cv::v_load(k)), a, b);
        low += a;
        high += b;
      }
      uint16_t block[16];
      cv::v_store(block, low);
      cv::v_store(block + 8, high);
      std::copy(block, block + 16, sums + start);
    }
    return;
  }
#endif
  std::fill(sums, sums + columns, 0u);
  for (int y = 0; y < rows; ++y, query += stride, keyframe += stride)
    for (int i = 0; i < columns; ++i)
      sums[i] += static_cast<uint32_t>(std::abs(static_cast<int>(query[i]) - static_cast<int>(keyframe[i])));
}

}  // namespace

std::string HomingParams::validate(int width, int rows) const
{
  std::ostringstream e;
  if (max_shift_px < 0 || 2 * max_shift_px >= width)
    e << "homing_max_shift_px must be in [0, " << (width - 1) / 2 << "] for " << width << " px wide images, got "
      << max_shift_px;
  else if (max_vertical_shift_px < 0 || max_vertical_shift_px >= rows)
    e << "homing_max_vertical_shift_px must be in [0, " << rows - 1 << "] for " << rows << " compared rows, got "
      << max_vertical_shift_px;
  else if (!(kept_column_share > 0.0 && kept_column_share <= 1.0))
    e << "homing kept_column_share must be in (0, 1], got " << kept_column_share;
  return e.str();
}

HomingEstimator::HomingEstimator(int width, int height, int first_row, const HomingParams& params)
  : width_(width), height_(height), first_row_(first_row), params_(params)
{
  if (width <= 0 || height <= 0 || first_row < 0 || first_row >= height)
    throw std::invalid_argument("HomingEstimator: need width, height > 0 and 0 <= first_row < height");
  const std::string invalid = params.validate(width, height - first_row);
  if (!invalid.empty())
    throw std::invalid_argument("HomingEstimator: " + invalid);
  column_sums_.resize(static_cast<size_t>(width));
  column_costs_.resize(static_cast<size_t>(2 * params.max_shift_px + 1) * width);
  if (params.robust_column_cost)
    sorted_costs_.resize(column_costs_.size());
  costs_.resize(static_cast<size_t>(2 * params.max_shift_px + 1));
}

const std::vector<double>& HomingEstimator::costs(const uint8_t* query, const uint8_t* keyframe)
{
  const int m = params_.max_shift_px, vertical = params_.max_vertical_shift_px;
  size_t all_columns = 0;
  for (int d = -m; d <= m; ++d)
  {
    // Query columns [begin, end) have a keyframe column x - d.
    const int begin = std::max(0, d), end = std::min(width_, width_ + d);
    const int columns = end - begin;
    float* column_cost = column_costs_.data() + static_cast<size_t>(d + m) * width_;
    std::fill(column_cost, column_cost + columns, std::numeric_limits<float>::infinity());
    for (int v = -vertical; v <= vertical; ++v)
    {
      // Query rows [first, last) have a keyframe row y - v below the sky.
      const int first = std::max(first_row_, first_row_ + v), last = std::min(height_, height_ + v);
      columnSums(query + static_cast<size_t>(first) * width_ + begin,
                 keyframe + static_cast<size_t>(first - v) * width_ + begin - d, static_cast<size_t>(width_),
                 last - first, columns, column_sums_.data());
      const float rows = static_cast<float>(last - first);
      for (int i = 0; i < columns; ++i)
        column_cost[i] = std::min(column_cost[i], static_cast<float>(column_sums_[i]) / rows);
    }
    if (params_.robust_column_cost)
    {
      std::copy(column_cost, column_cost + columns, sorted_costs_.begin() + all_columns);
      all_columns += static_cast<size_t>(columns);
    }
  }
  float scale_squared = 0.0f;
  if (params_.robust_column_cost)
  {
    // The median of all column costs (the mean of the two middle ones for an even count).
    const auto middle = sorted_costs_.begin() + all_columns / 2;
    std::nth_element(sorted_costs_.begin(), middle, sorted_costs_.begin() + all_columns);
    float median = *middle;
    if (all_columns % 2 == 0)
      median = 0.5f * (median + *std::max_element(sorted_costs_.begin(), middle));
    scale_squared = median * median;
  }
  for (int d = -m; d <= m; ++d)
  {
    const int columns = width_ - std::abs(d);
    float* column_cost = column_costs_.data() + static_cast<size_t>(d + m) * width_;
    if (scale_squared > 0.0f)
      for (int i = 0; i < columns; ++i)
        column_cost[i] = column_cost[i] * column_cost[i] / (column_cost[i] * column_cost[i] + scale_squared);
    const int kept =
        std::max(1, std::min(columns, static_cast<int>(std::lround(params_.kept_column_share * columns))));
    if (kept < columns)
      std::nth_element(column_cost, column_cost + (kept - 1), column_cost + columns);
    double sum = 0.0;
    for (int i = 0; i < kept; ++i)
      sum += column_cost[i];
    costs_[d + m] = sum / kept;
  }
  return costs_;
}

HomingEstimate HomingEstimator::estimate(const uint8_t* query, const uint8_t* keyframe)
{
  const std::vector<double>& cost = costs(query, keyframe);
  const int m = params_.max_shift_px;
  int best = m;
  for (int i = 0; i <= 2 * m; ++i)
    if (cost[i] < cost[best] || (cost[i] == cost[best] && std::abs(i - m) < std::abs(best - m)))
      best = i;
  HomingEstimate result;
  result.cost = cost[best];
  const int columns = width_ - std::abs(best - m);
  result.kept_columns =
      std::max(1, std::min(columns, static_cast<int>(std::lround(params_.kept_column_share * columns))));
  double shift = best - m;
  if (best > 0 && best < 2 * m)
  {
    const double left = cost[best - 1], centre = cost[best], right = cost[best + 1];
    if (params_.subpixel_fit == SubpixelFit::kParabola)
    {
      const double curvature = left - 2.0 * centre + right;
      if (curvature > 0.0)
        shift += 0.5 * (left - right) / curvature;
    }
    else
    {
      // Lines through the centre and the higher neighbour, and through the lower neighbour with the
      // opposite slope, cross at this offset (in [-0.5, 0.5]).
      const double rise = std::max(left, right) - centre;
      if (rise > 0.0)
        shift += 0.5 * (left - right) / rise;
    }
  }
  result.shift_px = shift;
  return result;
}

HomingParams clampedHomingParams(int width, int height, int first_row, int max_shift_px, int max_vertical_shift_px)
{
  HomingParams params;
  params.max_shift_px = std::max(0, std::min(max_shift_px, (width - 1) / 2));
  params.max_vertical_shift_px = std::max(0, std::min(max_vertical_shift_px, height - first_row - 1));
  return params;
}

double measureHomingShift(const uint8_t* query, const uint8_t* keyframe, int width, int height, int first_row,
                          int max_shift_px, int max_vertical_shift_px)
{
  HomingEstimator estimator(width, height, first_row,
                            clampedHomingParams(width, height, first_row, max_shift_px, max_vertical_shift_px));
  return estimator.estimate(query, keyframe).shift_px;
}

}  // namespace along_route_localization
