// Step 3a of the method: local contrast enhancement of a difference vector (paper eq. 2).
#ifndef ALONG_ROUTE_LOCALIZATION_CONTRAST_ENHANCEMENT_H
#define ALONG_ROUTE_LOCALIZATION_CONTRAST_ENHANCEMENT_H

#include <cstdint>

namespace along_route_localization
{

/// eq. 2: D^_i = (D_i - mean_l) / max(std_l, min_std), where mean_l and std_l (population) are taken
/// over the informative entries of the window [i - n, i + n] clipped to [0, count).
/// Entries with informative[i] == 0 (featureless keyframes or an uninformative query) and entries
/// whose window holds fewer than 2 informative values get `neutral` instead, so they neither attract
/// nor repel a path. Results are clamped to [-clamp, clamp]. `informative` may be null (all
/// informative). `out` may not alias `costs`. O(count) with running sums.
void enhanceContrast(const float* costs, const uint8_t* informative, int count, int half_window,
                     float min_std, float clamp, float neutral, float* out);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_CONTRAST_ENHANCEMENT_H
