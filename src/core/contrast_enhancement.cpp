#include "along_route_localization/contrast_enhancement.h"

#include <algorithm>
#include <cmath>

namespace along_route_localization
{

namespace
{

/// eq. 2 for one entry: (cost - mean) / max(std, min_std), clamped to [-clamp, clamp]; *peak becomes the
/// larger of itself and the unclamped score's negative.
float enhanced(double cost, double mean, double std, float min_std, float clamp, double* peak)
{
  const double z = (cost - mean) / std::max(static_cast<double>(min_std), std);
  *peak = std::max(*peak, -z);
  return static_cast<float>(std::min<double>(clamp, std::max<double>(-clamp, z)));
}

/// The statistics of eq. 2's window: for each of `count` items, the number, mean and population std of
/// the values of the used items in [i - half_window, i + half_window], with running sums (doubles keep
/// them exact enough). Calls emit(i, n, mean, std); mean and std are 0 when n is 0.
template <class Value, class Used, class Emit>
void slidingWindowStatistics(int count, int half_window, Value value, Used used, Emit emit)
{
  double sum = 0.0, sum_sq = 0.0;
  int n = 0;
  const auto add = [&](int i, int sign) {
    if (i < 0 || i >= count || !used(i))
      return;
    const double v = value(i);
    sum += sign * v;
    sum_sq += sign * v * v;
    n += sign;
  };
  for (int i = 0; i < std::min(half_window, count); ++i)
    add(i, +1);
  for (int i = 0; i < count; ++i)
  {
    add(i + half_window, +1);
    add(i - half_window - 1, -1);
    const double mean = n > 0 ? sum / n : 0.0;
    emit(i, n, mean, n > 0 ? std::sqrt(std::max(0.0, sum_sq / n - mean * mean)) : 0.0);
  }
}

}  // namespace

float enhanceContrast(const float* costs, const uint8_t* informative, int count, int half_window, float min_std,
                      float clamp, float neutral, float* out)
{
  double peak = 0.0;
  const auto used = [&](int i) { return informative == nullptr || informative[i] != 0; };
  slidingWindowStatistics(
      count, half_window, [&](int i) { return static_cast<double>(costs[i]); }, used,
      [&](int i, int n, double mean, double std) {
        out[i] = (!used(i) || n < 2) ? neutral : enhanced(costs[i], mean, std, min_std, clamp, &peak);
      });
  return static_cast<float>(peak);
}

float enhanceContrastRuns(const float* costs, const uint8_t* informative, const uint8_t* repeats, int count,
                          int half_window, float min_std, float clamp, float neutral, float* out,
                          ContrastRunsScratch* scratch)
{
  if (repeats == nullptr)
    return enhanceContrast(costs, informative, count, half_window, min_std, clamp, neutral, out);
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
  slidingWindowStatistics(
      runs, half_window, [&](int r) { return static_cast<double>(s.run_cost[r]); },
      [&](int r) { return s.run_informative[r] != 0; },
      [&](int r, int n, double mean, double std) {
        s.run_n[r] = n;
        s.run_mean[r] = static_cast<float>(mean);
        s.run_std[r] = static_cast<float>(std);
      });
  double peak = 0.0;
  for (int i = 0; i < count; ++i)
  {
    const int r = s.run_of[i];
    out[i] = ((informative != nullptr && !informative[i]) || s.run_n[r] < 2) ?
                 neutral :
                 enhanced(costs[i], s.run_mean[r], s.run_std[r], min_std, clamp, &peak);
  }
  return static_cast<float>(peak);
}

float rowWeight(float peak, float reference, float range)
{
  if (!(range > 0.0f) || !(reference > 0.0f))
    return 1.0f;
  return std::min(1.0f + range, std::max(1.0f - range, peak / reference));
}

}  // namespace along_route_localization
