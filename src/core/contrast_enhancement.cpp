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

}  // namespace along_route_localization
