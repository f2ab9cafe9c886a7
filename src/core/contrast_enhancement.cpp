#include "along_route_localization/contrast_enhancement.h"

#include <algorithm>
#include <cmath>

namespace along_route_localization
{

void enhanceContrast(const float* costs, const uint8_t* informative, int count, int half_window, float min_std,
                     float clamp, float neutral, float* out)
{
  // Running sums over the sliding window of informative entries; doubles keep them exact enough.
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  const auto use = [&](int i) { return informative == nullptr || informative[i] != 0; };
  const auto add = [&](int i, int sign) {
    if (i < 0 || i >= count || !use(i))
      return;
    sum += sign * static_cast<double>(costs[i]);
    sum_sq += sign * static_cast<double>(costs[i]) * costs[i];
    n += sign;
  };
  for (int i = 0; i < std::min(half_window, count); ++i)
    add(i, +1);
  for (int i = 0; i < count; ++i)
  {
    add(i + half_window, +1);
    add(i - half_window - 1, -1);
    if (!use(i) || n < 2)
    {
      out[i] = neutral;
      continue;
    }
    const double mean = sum / n;
    const double std = std::sqrt(std::max(0.0, sum_sq / n - mean * mean));
    const double z = (costs[i] - mean) / std::max(static_cast<double>(min_std), std);  // eq. 2
    out[i] = static_cast<float>(std::min<double>(clamp, std::max<double>(-clamp, z)));
  }
}

void enhanceContrastRuns(const float* costs, const uint8_t* informative, const uint8_t* repeats, int count,
                         int half_window, float min_std, float clamp, float neutral, float* out,
                         ContrastRunsScratch* scratch)
{
  if (repeats == nullptr)
  {
    enhanceContrast(costs, informative, count, half_window, min_std, clamp, neutral, out);
    return;
  }
  ContrastRunsScratch& s = *scratch;
  s.run_of.resize(count);
  s.run_cost.clear();
  s.run_informative.clear();
  for (int i = 0; i < count; ++i)
  {
    if (i == 0 || !repeats[i])
    {
      s.run_cost.push_back(costs[i]);
      s.run_informative.push_back(informative == nullptr || informative[i] != 0);
    }
    s.run_of[i] = static_cast<int>(s.run_cost.size()) - 1;
  }
  const int runs = static_cast<int>(s.run_cost.size());
  s.run_mean.resize(runs);
  s.run_std.resize(runs);
  s.run_n.resize(runs);
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  const auto add = [&](int r, int sign) {
    if (r < 0 || r >= runs || !s.run_informative[r])
      return;
    const double c = s.run_cost[r];
    sum += sign * c;
    sum_sq += sign * c * c;
    n += sign;
  };
  for (int r = 0; r < std::min(half_window, runs); ++r)
    add(r, +1);
  for (int r = 0; r < runs; ++r)
  {
    add(r + half_window, +1);
    add(r - half_window - 1, -1);
    s.run_n[r] = n;
    const double mean = n > 0 ? sum / n : 0.0;
    s.run_mean[r] = static_cast<float>(mean);
    s.run_std[r] = n > 0 ? static_cast<float>(std::sqrt(std::max(0.0, sum_sq / n - mean * mean))) : 0.0f;
  }
  for (int i = 0; i < count; ++i)
  {
    const int r = s.run_of[i];
    if ((informative != nullptr && !informative[i]) || s.run_n[r] < 2)
    {
      out[i] = neutral;
      continue;
    }
    const double z = (costs[i] - s.run_mean[r]) / std::max(static_cast<double>(min_std), static_cast<double>(s.run_std[r]));
    out[i] = static_cast<float>(std::min<double>(clamp, std::max<double>(-clamp, z)));
  }
}

}  // namespace along_route_localization
