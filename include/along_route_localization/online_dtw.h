// Step 4 of the method: online dynamic time warping over the ring buffer (paper section IV-C).
#ifndef ALONG_ROUTE_LOCALIZATION_ONLINE_DTW_H
#define ALONG_ROUTE_LOCALIZATION_ONLINE_DTW_H

#include <limits>
#include <vector>

#include "along_route_localization/cost_ring_buffer.h"

namespace along_route_localization
{

/// The cheapest sequence ending at the current frame, and how it compares with the rest.
struct SequenceMatch
{
  int keyframe = -1;          ///< end keyframe of the best path (current position), -1 if none
  float cost = 0.0f;          ///< best path cost divided by the number of rows it spans
  float second_cost = 0.0f;   ///< best cost among end keyframes farther than the exclusion radius
  bool has_second = false;    ///< false when every candidate lies inside the exclusion radius
  /// As second_cost, with the exclusion radius counted in runs of near-identical keyframes (see match):
  /// the best cost at another place, not merely at another copy of the same view.
  float second_place_cost = 0.0f;
  bool has_second_place = false;
  int rows = 0;               ///< rows of the ring buffer the path spans
  std::vector<int> path;      ///< keyframe per row, oldest first (filled by OnlineDtw only)
};

/// A motion model's prediction of the newest row's match, for OnlineDtw::match: the match is the end i
/// minimizing cost(i) + weight * min(|i - center|, cap), cost(i) being the accumulated cost per row.
/// A bounded penalty: within `cap` keyframes of the prediction it breaks near-ties between ends (a path
/// at a station or in a stretch of look-alike views wobbling a few keyframes ahead or behind); further
/// away it is a constant weight * cap, so evidence of a bigger jump (the robot crossed a station faster
/// than it taught) still moves the match. weight 0: no prior (the cheapest end).
struct EndPrior
{
  double center = 0.0;  ///< keyframe predicted (fractional)
  float weight = 0.0f;  ///< cost per row per keyframe away from the prediction
  float cap = std::numeric_limits<float>::infinity();  ///< keyframes beyond which the penalty stays flat
  bool ahead_only = false;  ///< only ends after the center pay (the robot cannot have moved on)
};

struct DtwParams
{
  int max_step = 2;            ///< s: steps (1,0), (1,1) ... (1,s) keyframes per frame
  /// Cost of a (1,0) stop that follows another stop. A single stop between moves is free, so any speed
  /// from s down to half the teach speed costs nothing, while a path parked on one keyframe pays
  /// this for every frame after the first.
  float stop_penalty = 1.0f;
  /// Cost of a (1,0) stop right after a move (0: free). A small value only breaks ties in favour of the
  /// nominal speed (one keyframe per frame), e.g. through a station where map and query both hold one
  /// view and every speed fits equally well. 0.05 is 1/40 of the clamp of one enhanced cost, so it never
  /// outweighs evidence: half speed (a stop every second frame) pays 0.025 per row.
  float first_stop_penalty = 0.05f;
  /// Cost of a (1,1) move right after a move or a skip (0: free). With first_stop_penalty it sets which
  /// speed wins where the views cannot tell speeds apart: cruiseSpeedTieBreak trades one for the other
  /// for a robot that drives slower than it taught.
  float move_penalty = 0.0f;
  /// Added per keyframe skipped beyond one, for (1,k), k >= 2, speeding up. Below 1, so that a stretch at
  /// twice the teach speed stays cheaper than losing the track. Cost units.
  float skip_penalty = 0.85f;
  /// As skip_penalty, for a (1,k), k >= 2, that follows another such step: a robot that keeps driving
  /// faster than it taught pays on speeding up only when this is 0. Equal to skip_penalty, every skip
  /// pays the same (the plain recursion).
  float sustained_skip_penalty = 0.4f;
  float missing_cost = 1.0f;   ///< cost of a keyframe a row did not compute (outside its band)
  int exclusion_radius = 5;    ///< keyframes around the best end ignored for second_cost
  /// Subtract from every keyframe its mean cost over the rows in the window that computed it (missing_cost
  /// is neither averaged in nor centred) before accumulating, so a keyframe that resembles every query (a
  /// generic view) cannot carry a path by itself. Rows flagged
  /// repeatedQuery (except the oldest) are left out of the mean, and the mean of the D distinct rows
  /// is scaled by (D - 1) / (K' - 1) for K' rows: a window of one view held K' times (D = 1) is not
  /// centred at all, instead of to zero everywhere (which would tie every keyframe).
  bool column_centering = true;
};

/// The step costs for a robot that cruises at `cruise_speed` keyframes per frame (its long-run speed along
/// the map), from `params` set for the nominal speed of one keyframe per frame: the tie-break
/// first_stop_penalty is shared between a stop after a move (a share a) and a move after a move (1 - a),
/// a = clamp((cruise_speed - 0.5) / 0.5, 0, 1). At 1 keyframe per frame or faster that is `params`
/// itself; at half speed (a map taught with twice the frame spacing, or a robot driving at half its
/// teach speed) alternating stops and moves is free and straight moves pay instead, so through views that
/// cannot tell speeds apart (a dark stretch, a station) the path goes on at the robot's speed, not at
/// the nominal one. Every other field is kept.
DtwParams cruiseSpeedTieBreak(const DtwParams& params, double cruise_speed);

/// Accumulated cost, row by row from the oldest row in the buffer to the newest, in three states per
/// keyframe: M (the last step was (1,1)), F (the last step skipped: (1,k), k >= 2) and S (a stop):
///   M_r(i) = C_r(i) + min( M_{r-1}(i-1) + move_penalty, S_{r-1}(i-1), F_{r-1}(i-1) + move_penalty )
///   F_r(i) = C_r(i) + min_{k=2..s} min( min(M_{r-1}(i-k), S_{r-1}(i-k)) + (k - 1) * skip_penalty,
///                                      F_{r-1}(i-k) + (k - 1) * sustained_skip_penalty )
///   S_r(i) = C_r(i) + min( min(M_{r-1}(i), F_{r-1}(i)) + first_stop_penalty, S_{r-1}(i) + stop_penalty )
/// (C centred per keyframe over the rows that computed it when column_centering is set). The match is
/// argmin_i min(M, S, F)_newest(i) over the candidate end keyframes [first_end, first_end + count), or,
/// with an EndPrior, the end minimizing that cost plus the prior's penalty.
/// Because the accumulation spans only the K rows held, a wrong stretch falls out of the window and
/// the path recovers; because every candidate end is scored, the match may leave [last, last + s]
/// (the Localizer, while tracking, limits how far it may jump: match's first_choice and last_choice).
class OnlineDtw
{
public:
  explicit OnlineDtw(const DtwParams& params = DtwParams());
  void setParams(const DtwParams& params);
  const DtwParams& params() const { return params_; }
  /// true (the default): a window of 4096 keyframes or more (a global search on a big map) is split into
  /// column chunks run by cv::parallel_for_; false: every window in one piece on the calling thread. The
  /// result is the same either way.
  void setParallel(bool parallel) { parallel_ = parallel; }

  /// Uses the newest min(rows, buffer.size()) rows. With `backtrack` the best path is returned too.
  /// Reuses internal buffers: no allocation once they have grown to the largest band seen.
  /// keyframe_run (optional, indexed by keyframe over the whole map, non-decreasing) numbers the runs of
  /// near-identical keyframes (a station where the teach camera stood still is one run): the exclusion
  /// radius of second_place_cost is counted in runs, so copies of the best keyframe's view are not
  /// taken for another place. Without it second_place_cost = second_cost.
  /// first_choice, last_choice: the match is the cheapest end in [first_choice, last_choice] (clamped to
  /// [first_end, first_end + count), at least one end); ends outside are not chosen but still compete for
  /// second_cost and second_place_cost, so a cheaper path ending there shows as a margin of zero (the
  /// Localizer, while tracking, does not jump to another place: that is for its loss detection and
  /// global search).
  /// prior: see EndPrior; it only chooses among the ends (SequenceMatch::cost stays the chosen end's
  /// accumulated cost, so a cheaper end elsewhere still lowers the margins).
  /// path_start >= 0: every path starts at that keyframe in the oldest row (a known start: the robot
  /// was there on the first frame of the window); ends it cannot reach are infinitely dear. -1: anywhere.
  SequenceMatch match(const CostRingBuffer& buffer, int first_end, int count, int rows,
                      bool backtrack = false, const int* keyframe_run = nullptr, int first_choice = 0,
                      int last_choice = std::numeric_limits<int>::max(), const EndPrior& prior = EndPrior(),
                      int path_start = -1);

  /// Accumulated cost row of the last match() (per end keyframe, divided by rows), for display.
  const std::vector<float>& lastAccumulated() const { return last_row_; }
  /// The column chunks the last match() ran in (1: one piece).
  int lastChunks() const { return last_chunks_; }

private:
  /// The columns [lo, lo + width) a match looks at, and how.
  struct Window
  {
    int lo = 0, width = 0, rows = 0;
    bool backtrack = false;
    int path_start = -1;  ///< keyframe every path starts at in the oldest row, -1: anywhere
  };
  /// Per column chunk: the rows being accumulated, the centred costs and the column means.
  struct Columns
  {
    std::vector<float> prev_move, prev_stop, prev_fast, cur_move, cur_stop, cur_fast, costs, mean, count;
  };
  /// The recurrence for window columns [begin, end): the newest row into final_*, steps when backtracking.
  void accumulateColumns(const CostRingBuffer& buffer, const Window& window, int begin, int end, Columns& scratch);

  DtwParams params_;
  bool parallel_ = true;
  int last_chunks_ = 0;
  std::vector<Columns> columns_;  // one per chunk (wide windows are split over threads)
  std::vector<float> final_move_, final_stop_, final_fast_, last_row_;
  // Backtracking, rows x width per state (M, S, F): bits 0-4 the step k, bits 5-6 the state it came from (1-3).
  std::vector<unsigned char> move_steps_, stop_steps_, fast_steps_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ONLINE_DTW_H
