// Step 5's confidence as a probability: a forward filter (a hidden Markov model) over where along the
// route the robot is, fed with the same image differences as the sequence matcher.
#ifndef ALONG_ROUTE_LOCALIZATION_ROUTE_POSTERIOR_H
#define ALONG_ROUTE_LOCALIZATION_ROUTE_POSTERIOR_H

#include <cstdint>
#include <string>
#include <vector>

namespace along_route_localization
{

/// The model's four numbers (LocalizerParams::posterior): the middle of the plateau the folds chose by
/// cross-validation, picked on all six folds (doc/results.md, "The confidence as a posterior over the route").
struct PosteriorParams
{
  /// The likelihood of a keyframe given one frame: exp(-(c - c_min) / cost_scale), c being the frame's
  /// energy-normalized SAD with that keyframe (step 2b) and c_min the least of the frame's row. In the
  /// units of the energy-normalized cost (two unrelated textured images: about 1).
  double cost_scale = 0.03;
  /// Probability per frame that the robot's speed changes by half a keyframe per frame, up or down.
  double speed_change = 0.02;
  /// Probability per frame that the robot is anywhere on the route (carried elsewhere: a kidnapping).
  double jump = 0.01;
  /// Share of the belief a known start (start_keyframe) leaves spread over the whole route.
  double start_doubt = 0.9;
  /// Fastest speed, keyframes per frame (the DTW's s).
  int max_step = 2;

  /// Empty when usable, else what is wrong.
  std::string validate() const;
};

/// p(position, speed | frames so far). Positions are the keyframes and the midpoints between neighbours
/// (2n - 1 of them), speeds 0, 1/2, ..., max_step keyframes per frame. Each frame: the speed changes by
/// half a step with probability speed_change, the position moves on by the speed (at the route's end it
/// stays there), and with probability jump the robot is anywhere; then the belief is weighed by the frame's
/// likelihood (a midpoint by the geometric mean of its two keyframes'). The published confidence is the
/// mass within one keyframe of the answer (withinOne), so it is a probability by construction.
///
/// The belief is held on a window of keyframes, those the frame was compared with (the tracking band, or
/// the whole map on a global search), plus one number: the mass elsewhere, taken as spread evenly over the
/// positions outside the window. A frame costs O(window x speeds), independent of the map's size while
/// tracking; on a global search the window is the whole map and the filter exact.
class RoutePosterior
{
public:
  explicit RoutePosterior(const PosteriorParams& params = PosteriorParams());
  /// Throws std::invalid_argument when params.validate() says so. Changing max_step keeps each position's
  /// mass, spread evenly over the new speeds.
  void setParams(const PosteriorParams& params);
  const PosteriorParams& params() const { return params_; }

  /// A new drive on a route of `keyframes` (>= 1): at `start` (a keyframe; start_doubt of the belief spread
  /// over the route) or anywhere (start < 0). The window is the whole route.
  void reset(int keyframes, int start);

  /// The window becomes the keyframes [first, first + width) (clipped to the route; nothing left: unchanged):
  /// those a frame is compared with, whether or not it brings evidence. What leaves the window joins the even
  /// spread elsewhere; what enters it takes the spread's share.
  void moveTo(int first, int width);

  /// `frames` frames without evidence (missed, or featureless): the motion model only.
  void predict(int frames = 1);

  /// One frame's evidence after its predict(): costs[j] for keyframe first + j, j < width (entries off the
  /// route are ignored); a keyframe with usable[j] == 0 (featureless) or a cost that is not finite takes the
  /// median likelihood of the usable ones, as do the positions outside the window, which becomes the row's
  /// keyframes (moveTo). No usable keyframe: no evidence, the window unchanged.
  void observe(const float* costs, const uint8_t* usable, int first, int width);

  /// The probability that the robot is at `keyframe` (its position and half of each neighbouring midpoint).
  double keyframeMass(int keyframe) const;
  /// The probability that the robot is within one keyframe of `keyframe`: the published confidence.
  double withinOne(int keyframe) const;
  /// The most likely keyframe in the window.
  int mostLikely() const;
  int keyframes() const { return keyframes_; }
  int windowFirst() const { return lo_; }
  int windowWidth() const { return hi_ - lo_; }

private:
  int speeds() const { return 2 * params_.max_step + 1; }
  int positions() const { return 2 * (hi_ - lo_) - 1; }       ///< in the window
  int allPositions() const { return 2 * keyframes_ - 1; }    ///< on the route
  /// The mass of one position outside the window, all speeds together.
  double outsideDensity() const;
  double positionMass(int x) const;  ///< x: a position of the route (2 * keyframe for a keyframe)
  void normalize();

  PosteriorParams params_;
  int keyframes_ = 0;
  int start_ = -1;
  int lo_ = 0, hi_ = 0;        ///< the window's keyframes [lo_, hi_)
  std::vector<double> p_;      ///< [speed * positions() + x - 2 * lo_]
  std::vector<double> next_;   ///< scratch, as p_
  std::vector<double> log_likelihood_, usable_values_;  ///< observe()'s scratch: no allocation once grown
  double elsewhere_ = 0.0;     ///< the mass outside the window
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROUTE_POSTERIOR_H
