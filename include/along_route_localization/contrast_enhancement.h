// Step 3a of the method: local contrast enhancement of a difference vector (paper eq. 2), and the
// weight of the enhanced row (an extension).
#ifndef ALONG_ROUTE_LOCALIZATION_CONTRAST_ENHANCEMENT_H
#define ALONG_ROUTE_LOCALIZATION_CONTRAST_ENHANCEMENT_H

#include <cstdint>
#include <vector>

namespace along_route_localization
{

/// The localizer's min_std of eq. 2 (cost units). Not a parameter (it was contrast_min_std): it only keeps a
/// flat difference vector (every keyframe as far from the query) from dividing by zero. The value of 0.01
/// is the default the parameter had, so results are unchanged.
constexpr float kContrastMinStd = 0.01f;

/// eq. 2: D^_i = (D_i - mean_l) / max(std_l, min_std), where mean_l and std_l (population) are taken
/// over the informative entries of the window [i - n, i + n] clipped to [0, count).
/// Entries with informative[i] == 0 (featureless keyframes or an uninformative query) and entries
/// whose window holds fewer than 2 informative values get `neutral` instead, so they neither attract
/// nor repel a path. Results are clamped to [-clamp, clamp]. `informative` may be null (all
/// informative). `out` may not alias `costs`. O(count) with running sums.
/// Returns the row's peak: the largest score below the mean before the clamp,
/// max_i (mean_l - D_i) / max(std_l, min_std) over the scored entries (0 if none is below its mean),
/// i.e. how far the best match of the row stands out from its neighbours (rowWeight).
float enhanceContrast(const float* costs, const uint8_t* informative, int count, int half_window,
                      float min_std, float clamp, float neutral, float* out);

/// Reusable storage of enhanceContrastRuns (no allocation once grown to the largest count seen).
struct ContrastRunsScratch
{
  std::vector<float> run_cost, run_mean, run_std;
  std::vector<uint8_t> run_informative;
  std::vector<int> run_of, run_n;
};

/// eq. 2 with the window counted in runs of near-identical keyframes instead of keyframes.
/// repeats[i] != 0 marks keyframe i as a copy of keyframe i - 1 (the teach camera stood still;
/// repeats[0] is ignored). A run is represented by its first entry's cost and informative flag, and
/// the window of every entry of run r is the runs [r - n, r + n]: a station where the map holds many
/// copies of one view counts once, so it neither fills the window with the true match's own cost (which
/// would score it neutral) nor outweighs the places around it. Each entry is then scored with its own
/// cost, D^_i = (D_i - mean_r) / max(std_r, min_std), clamped, `neutral` as in enhanceContrast.
/// Equals enhanceContrast when repeats is null or all zero (the returned peak too). O(count).
float enhanceContrastRuns(const float* costs, const uint8_t* informative, const uint8_t* repeats, int count,
                          int half_window, float min_std, float clamp, float neutral, float* out,
                          ContrastRunsScratch* scratch);

/// Weight of one enhanced row in the sequence (step 3a, an extension of the paper): a query whose best
/// match stands out clearly from its neighbours (a high eq. 2 peak) is likelier to be matched to the right
/// keyframe than one whose best match barely does (a query halfway between two keyframes of a sparse map,
/// a look-alike stretch), so its row counts more in the DTW:
///   w = clamp(peak / reference, 1 - range, 1 + range);   range 0: every row weighs 1 (the paper).
float rowWeight(float peak, float reference, float range);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_CONTRAST_ENHANCEMENT_H
