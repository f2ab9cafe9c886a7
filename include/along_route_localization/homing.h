// The homing estimate: how far the scene of a query lies to the right of the matched keyframe's, in px of
// the preprocessed image, measured over the whole image width and robust to the parts that changed.
#ifndef ALONG_ROUTE_LOCALIZATION_HOMING_H
#define ALONG_ROUTE_LOCALIZATION_HOMING_H

#include <cstdint>
#include <string>
#include <vector>

namespace along_route_localization
{

/// How the best integer shift's cost and its neighbours' refine it to subpixel.
enum class SubpixelFit
{
  kParabola,    ///< vertex of the parabola through the three costs (exact for squared differences)
  kEquiangular  ///< crossing of two lines of opposite slopes through them (exact for SAD on a linear ramp)
};

/// How the homing estimate is measured (homingShift, homing.cpp). doc/results.md, Homing.
struct HomingParams
{
  /// Shifts searched, [-max_shift_px, max_shift_px], px of the preprocessed image. Wider than the
  /// matching's max_shift_px: a robot turned 10 degrees off its route (1 rad field of view, 64 px)
  /// sees its scene displaced 10 px.
  int max_shift_px = 16;
  /// Vertical offsets tried for each column, [-max_vertical_shift_px, max_vertical_shift_px], px: the
  /// camera's pitch and height differ between the teach and the repeat (a slope, a load, another robot).
  int max_vertical_shift_px = 2;
  /// At each shift, only this share of the overlapping columns, those that match best, count: a column
  /// whose content changed (a parked car, foliage, snow) matches badly at every shift and is left out.
  /// 1 = every overlapping column. Share in (0, 1].
  double kept_column_share = 1.0;
  SubpixelFit subpixel_fit = SubpixelFit::kEquiangular;
  /// Geman-McClure column costs: each column's cost c counts as c^2 / (c^2 + s^2), s the median of the
  /// column costs of this pair over every shift (its typical mismatch, no parameter to tune), so a column
  /// that matches nowhere (changed content) adds at most 1 at every shift instead of its full cost, while
  /// columns that match well weigh as their squared cost. False: c counts as is. Default: what
  /// leave-one-place-out chooses on the Stromovka pairs (doc/results.md, Homing).
  bool robust_column_cost = true;

  /// Empty when valid for images of `width` px and `rows` compared rows, otherwise a sentence naming the
  /// invalid field.
  std::string validate(int width, int rows) const;
};

/// A homing estimate.
struct HomingEstimate
{
  double shift_px = 0.0;  ///< query(x) ~ keyframe(x - shift_px): scene content moved shift_px to the right
  /// At the best shift: the mean over the kept columns of each column's mean absolute byte difference
  /// at its best vertical offset.
  double cost = 0.0;
  int kept_columns = 0;   ///< columns that counted at the best shift
};

/// Measures the shift between a query and a keyframe, both width x height bytes (rows contiguous, the
/// preprocessed images of step 1), rows [first_row, height) compared (rows above are sky).
/// For every integer shift d in [-m, m], each query column x whose counterpart x - d lies in the
/// keyframe gets the cost min over v in [-V, V] of the mean over rows y of |query(y, x) - keyframe(y - v,
/// x - d)| (rows y and y - v both in [first_row, height): each column finds its own vertical offset);
/// the cost of d is the mean of the kept_column_share lowest of these column costs (at least one): a
/// trimmed mean over the columns that overlap at d (so the whole width counts, and wide shifts are not
/// favoured for comparing fewer columns). The best d is refined to subpixel from its cost and its two
/// neighbours' (subpixel_fit; ties go to the smallest |d|: no evidence of a turn, none reported).
/// With robust_column_cost, each column cost c is first replaced by c^2 / (c^2 + s^2), s the median
/// column cost of the pair over all shifts (HomingParams::robust_column_cost).
/// Cost: (2m + 1) * (2V + 1) * width * (height - first_row) byte differences at most per estimate, no
/// allocation.
class HomingEstimator
{
public:
  /// Throws std::invalid_argument for a size or params that leave nothing to compare.
  HomingEstimator(int width, int height, int first_row, const HomingParams& params = HomingParams());

  const HomingParams& params() const { return params_; }
  int width() const { return width_; }
  int height() const { return height_; }
  int firstRow() const { return first_row_; }

  /// The shift of `query` relative to `keyframe`.
  HomingEstimate estimate(const uint8_t* query, const uint8_t* keyframe);

  /// The trimmed-mean cost of every shift -m..m (index d + m), as estimate() computes them.
  const std::vector<double>& costs(const uint8_t* query, const uint8_t* keyframe);

private:
  int width_, height_, first_row_;
  HomingParams params_;
  std::vector<uint32_t> column_sums_;  // scratch: one shift's column sums at one vertical offset
  std::vector<float> column_costs_;   // scratch: every shift's column costs, (2m + 1) rows of width
  std::vector<float> sorted_costs_;   // scratch: their copy for the median (robust_column_cost)
  std::vector<double> costs_;           // scratch: the cost per shift
};

/// HomingParams with the two search ranges the Localizer exposes, lowered to what the image size allows
/// ((width - 1) / 2 and height - first_row - 1), the other parameters at their defaults.
HomingParams clampedHomingParams(int width, int height, int first_row, int max_shift_px, int max_vertical_shift_px);

/// The shift_px of HomingEstimator(width, height, first_row, clampedHomingParams(...)) for one pair: what the
/// Localizer (which keeps its estimator) reports for its matched keyframe. Builds an estimator per call.
double measureHomingShift(const uint8_t* query, const uint8_t* keyframe, int width, int height, int first_row,
                          int max_shift_px, int max_vertical_shift_px);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_HOMING_H
