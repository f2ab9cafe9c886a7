// Steps 2-5 put together: one preprocessed frame in, one localization out.
#ifndef ALONG_ROUTE_LOCALIZATION_LOCALIZER_H
#define ALONG_ROUTE_LOCALIZATION_LOCALIZER_H

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "along_route_localization/contrast_enhancement.h"
#include "along_route_localization/cost_ring_buffer.h"
#include "along_route_localization/homing.h"
#include "along_route_localization/image_difference.h"
#include "along_route_localization/online_dtw.h"
#include "along_route_localization/route_map.h"
#include "along_route_localization/route_posterior.h"
#include "along_route_localization/seqslam.h"
#include "along_route_localization/track_status.h"

namespace along_route_localization
{

enum class LocalizationStatus
{
  kInitializing,  ///< collecting frames for the first global sequence search (the start unknown)
  kTracking,      ///< following the route within the search band (from a known start: start_keyframe)
  kLost,          ///< confidence stayed low; searching the whole map again
  kEndOfRoute     ///< tracking, and the match is within the last keyframes of the map
};
std::string toString(LocalizationStatus status);

enum class SequenceMethod
{
  kOnlineDtw,  ///< the method of this package
  kSeqSlam     ///< straight-line baseline, always global
};
std::string toString(SequenceMethod method);
bool sequenceMethodFromString(const std::string& name, SequenceMethod* method);

/// Parameters of steps 2-5. Units in the comments; the parameter table (parameters.h) gives each one's
/// working range, which validate() checks.
struct LocalizerParams
{
  SequenceMethod method = SequenceMethod::kOnlineDtw;
  CostFunction cost_function = CostFunction::kSad;
  int ring_buffer_rows = 30;          ///< K, frames in the sequence window
  int max_shift_px = 4;               ///< m, horizontal shift search range, px of the preprocessed image
  /// Horizontal bands of the compared rows that each take their own shift in [-m, m] (ImageDifference):
  /// 1, the paper's one shift for the whole strip; 2 for a repeat beside the taught line, where the near
  /// ground low in the view moves more than what is far (doc/results.md, "A repeat beside the taught line").
  int shift_bands = 1;
  /// Vertical offsets, [-V, V] rows of the preprocessed image, at which each keyframe is also compared
  /// (ImageDifference): 0, the paper's level comparison; 1-2 for a camera that pitches and rolls (a rover on
  /// rough ground: doc/results.md, "A camera that pitches and rolls"). Not for the census cost, nor the
  /// coarse global search of big maps.
  int max_vertical_shift_px = 0;
  bool subpixel_shift = true;
  int contrast_window = 10;           ///< n, eq. 2 half window, keyframes
  float contrast_clamp = 2.0f;        ///< |enhanced cost| limit
  /// Step 3a, rowWeight (an extension of the paper): while tracking, each row is weighed by
  /// clamp(peak / row_weight_reference, 1 - row_weight_range, 1 + row_weight_range), the peak being how
  /// many standard deviations (eq. 2) its best keyframe stands out. Reference: a peak, in standard
  /// deviations; range: dimensionless. Range 0: every row weighs 1.
  float row_weight_reference = 2.25f;
  float row_weight_range = 0.2f;
  /// A frame or keyframe whose textureEnergy is below min_texture_ratio * the map's median keyframe
  /// energy is featureless (near-black, blank). Relative, so it holds for every normalization method.
  float min_texture_ratio = 0.4f;
  /// Two images (consecutive keyframes, or a query and the previous query) whose mean absolute byte
  /// difference is below stationary_ratio * the map's median difference between consecutive keyframes
  /// show the same view: the camera stood still. Used by eq. 2 (a run of such keyframes counts once,
  /// enhanceContrastRuns) and by column centering (rows of a repeated query are flagged, OnlineDtw).
  /// 0 = off.
  float stationary_ratio = 0.2f;
  /// Divide each SAD by the sum of the two images' texture energies (step 2b), so that partly
  /// featureless keyframes do not look similar to every query.
  bool energy_normalized_cost = true;
  int search_radius = 40;             ///< keyframes computed on each side of the predicted match while tracking
  /// Inside a run of near-identical keyframes (the teach camera stood still, see stationary_ratio, or
  /// saw nothing) the images cannot tell the keyframes apart: while tracking, report the keyframe reached
  /// at the speed the DTW path had when it entered the run (keyframeThroughRun) instead of the DTW's pick
  /// among the look-alikes. Off: the DTW's pick.
  bool run_dead_reckoning = true;
  /// On maps of at least this many keyframes (0: never) a global search compares 2x2-averaged images
  /// (halveImage) with a shift range of ceil(m / 2): a quarter of the bytes and about half the shifts. The
  /// answer's reported shift is still measured at full resolution; tracking always is, but for the rows of
  /// a known start's check (start_keyframe), which serve its global search too.
  int coarse_search_keyframes = 4096;
  /// While tracking, the new match continues from the last one (L): it is chosen among the ends
  /// [L - dtw.exclusion_radius, L + dtw.max_step + max_jump_ahead] of the band. Further back or further
  /// ahead is another place, left to the loss detection and the global search (a cheaper path there
  /// still lowers the confidence). The slack ahead is wider than behind: answers lag the robot more
  /// often than they lead it (after stations and tunnels crossed at the speed of arrival). Keyframes.
  int max_jump_ahead = 15;
  /// Motion prior on the new match while tracking (EndPrior): each candidate end pays this much cost per
  /// row per keyframe away from where the robot is predicted to be, up to motion_prior_cap keyframes
  /// (motionPrior has the prediction). The DTW's cheapest end wobbles where the views look alike (2:1
  /// map spacing, stations): one keyframe off the prediction costs 0.02 per row, 0.6 over K = 30 rows,
  /// against 0.85 for one skip. Cost units per row per keyframe; 0 = off.
  float motion_prior_weight = 0.02f;
  /// Keyframes beyond which the motion prior's penalty stays flat, so stronger evidence can still move
  /// the match further (a station crossed at another speed than taught leaves the answer behind). Not
  /// applied while the query repeats the last view: a repeated view brings no evidence for a jump.
  float motion_prior_cap = 3.0f;
  /// Frames over which the robot's cruise speed (keyframes per frame along the map) is averaged: the
  /// mean of the tracked answer's steps between informative frames (the nominal speed of 1 counts as the
  /// first), from the cruise_speed_frames-th on an exponential moving average over that many. The DTW's
  /// tie-break between speeds follows it (cruiseSpeedTieBreak): a robot that drives at half the speed it
  /// taught, or a map taught with twice the frame spacing, is followed at half speed through views that
  /// cannot tell speeds apart, instead of at one keyframe per frame. When the track moves to another place
  /// (a refuted start, a carried robot found, a place confirmed after a loss) the steps since the last
  /// confident answer are dropped: the speed is what it was there, that answer's own step included (the
  /// nominal 1 if there was none but on a known start under its check, which is only assumed). Frames;
  /// 0 = off (the nominal speed always).
  int cruise_speed_frames = 100;
  DtwParams dtw;                      ///< s (max_step), stop and skip penalties, exclusion radius
  SeqSlamParams seqslam;              ///< baseline only
  /// The newest relocalization_rows queries, compared again with the whole map: (1) when the track is
  /// lost, the global search starts from them instead of an empty window (they are frames the robot has
  /// seen, and the loss was judged on them; the rows of the lost track are dropped: they covered only its
  /// band; at most K - 1 are used); (2) while tracking, whenever they alone do not support the track's
  /// end, so that a robot carried elsewhere is found there as soon as they show it, not K / 2 frames later
  /// when the whole window stops supporting the old place (recentCheck; a check that has found the track
  /// contradicted goes on while they support it, until they also end at the track over the whole map).
  /// Each such frame computes their
  /// whole-map rows (while a check goes on, only those of the frames since its last one), so it costs
  /// about as much as a global frame (doc/results.md, Performance); the check's window grows by each frame
  /// it goes on for, up to K rows, and after K checks in a row found no place elsewhere the check rests
  /// until the track is supported again. At most K are used.
  /// 0 = neither: an empty window after a loss, no check.
  int relocalization_rows = 8;
  /// Where the robot starts, on the first frame after construction or reset() (a new map, time going
  /// back in a looping bag). >= 0: at this keyframe (teach and repeat: the repeat starts where the teach
  /// did), tracked from the first frame, every path starting there while that frame is in the window;
  /// a global search over the same rows still runs, and takes over when it confirms another place that
  /// its first answer already showed (startRefuted: a robot started mid-route). -1: unknown, a global
  /// search (min_init_frames, init_confirm_frames) before any tracking. Must be below the map's size.
  int start_keyframe = 0;
  /// The robot may be carried elsewhere (the kidnapped robot) or started elsewhere than start_keyframe:
  /// while a track holds, a global search looks for it elsewhere (the known start's check, startRefuted;
  /// the newest frames' check, recentCheck) and moves the track there on their evidence. false: the robot
  /// only moves as it drives, from start_keyframe (a closed-loop repeat from its start, follow.launch): a
  /// track moves only through the loss detection and the global search after it, whose match ends only
  /// where the robot could have driven since the loss: from search_radius keyframes behind the lost track to
  /// dtw.max_step keyframes a frame ahead of it. Over 8-14 frames a
  /// look-alike stretch of a route can be supported as well as a real kidnapping's place is (issue 31:
  /// the closed loop's two stalls), and no margin the images give tells them apart; what does is knowing
  /// that the robot drives.
  bool detect_kidnapping = true;
  int min_init_frames = 5;            ///< frames before the first global answer
  /// Consecutive informative frames whose global answer is confident and advances 0..max_step keyframes
  /// per frame before tracking starts (GlobalConfirmation). Confident here: the confidence in the place
  /// weighed by the distinct views among the K rows, as the published confidence (Localizer::process), so
  /// copies of one view (a camera standing still) or a few rows need a wider margin.
  int init_confirm_frames = 5;
  double confidence_threshold = 0.2;  ///< below it a frame counts as low-confidence
  /// Per-row cost margin that maps to confidence 1 - 1/e (over a full window of K rows; the reported
  /// confidence weighs the margin by the distinct views among the rows / K, Localizer::process).
  float confidence_scale = 0.5f;
  /// Step 5: the published confidence is the probability that the answer is within one keyframe of the
  /// true one, sigma(calibration_offset + calibration_slope * c), c being the route posterior's mass within
  /// one keyframe of the answer (posterior_confidence, below) or the margin confidence above
  /// (calibratedConfidence; a logistic fit, Platt scaling). scripts/cross_validate fits both on real
  /// frames, reports the calibration error on folds the fit did not see, and prints the fit for a route
  /// of your own. calibration_slope 0: publish c itself. A lost track's answer has 0. Both dimensionless.
  float calibration_offset = 0.143f;
  float calibration_slope = 5.113f;
  /// Step 5, the confidence a probability: with posterior_confidence (the default) c above is not the DTW's
  /// margin but the mass within one keyframe of the answer of a forward filter over the route
  /// (RoutePosterior, route_posterior.h), fed with each frame's energy-normalized costs over the keyframes
  /// it was compared with. The margin confidence still drives the status (confidence_threshold, the loss
  /// detection, the confirmations). posterior.max_step is the DTW's (set by the Localizer).
  bool posterior_confidence = true;
  PosteriorParams posterior;
  /// Lost (global search again) when lost_after_frames of the last lost_window_frames informative
  /// frames were low-confidence (LossDetector). Featureless frames do not count, nor do copies of the
  /// last view (the camera standing still): they bring no evidence of another place, and a long stop at
  /// a station that looks like others made the track lost (Localizer.StandingStillDoesNotMakeTheTrackLost).
  int lost_after_frames = 6;
  int lost_window_frames = 8;
  /// Weak evidence is not contrary evidence: when the loss detection fires, the last relocalization_rows
  /// frames are compared with the whole map as a sequence (trackContradicted), and the track is lost only
  /// when they support another place, confidently, better than the tracked one. Otherwise (snow, fog, a
  /// featureless plain: the images neither confirm nor contradict the track) the track goes on, with the
  /// low confidence the images give it, its answer dead-reckoned at the cruise speed from the last
  /// confident one until a frame is confident again. A track no evidence established yet (a known start
  /// under its check) and one dead-reckoned past the route's last keyframe are lost as before. While
  /// coasting, a check whose sequence places the robot next to the dead-reckoned keyframe, or where it can
  /// have driven and better than there by more than chance, moves the dead reckoning there
  /// (trackContradicted). Off: every loss detection loses the track (before 2026-11-27's twenty-first round).
  bool loss_needs_contradiction = true;
  /// While lost, answer with the dead-reckoned keyframe (the last tracked one, moved on at the cruise speed
  /// since the loss) with confidence 0, never the unconfirmed guess of the global search. Off: the guess.
  bool dead_reckon_while_lost = false;
  /// Another place contradicts the track (a check while tracking, or while coasting) only when its
  /// sequence also beats the track's end by more than this share of chanceMargin (a wrong stretch's margin
  /// over another on this map, measured on load); 0: by its place confidence alone.
  double contradiction_margin_share = 0.75;
  int end_of_route_keyframes = 2;     ///< a match this close to the last keyframe reports kEndOfRoute
  /// A gap in the frames' stamps (FrameClock) is frames the camera missed: they go through skipFrames
  /// before the frame after the gap. Off for a camera triggered by distance travelled, whose gaps are stops.
  bool fill_frame_gaps = true;
  double horizontal_fov_rad = 1.0;    ///< camera horizontal field of view, for the homing angle
  /// The reported shift (and homing angle) of the matched keyframe is measured by HomingEstimator over
  /// the whole width, searching +-homing_max_shift_px px horizontally and, for each column,
  /// +-homing_max_vertical_shift_px px vertically (HomingParams; doc/results.md, Homing).
  int homing_max_shift_px = 16;
  int homing_max_vertical_shift_px = 2;
  bool parallel = true;               ///< spread global searches over cores

  std::string validate() const;
  /// What the images' size refuses (empty: nothing): max_shift_px below half the width, shift_bands at most
  /// the compared rows (firstComparedRow on). The localizer checks it against its map's preprocessing;
  /// localize_offline --check-params against the preprocessing it was given.
  std::string validateForImages(const PreprocessingParams& images) const;
};

/// First image row compared for images preprocessed with `images`: below the sky rows, leaving at least one.
int firstComparedRow(const PreprocessingParams& images);

/// What the robot's own motion sensing (wheel odometry, or the velocity it was commanded) says it did since
/// the previous frame (the localizer nodelet's optional motion topic).
enum class RobotMotion
{
  kUnknown,    ///< nothing said: the images alone decide
  kStoodStill, ///< the robot did not move: a featureless frame is then no frame at all (Localizer::process)
  kMoved       ///< the robot moved: the images decide, as with kUnknown
};

/// From the robot's velocity samples (odometry or commands), what it did between two frames: kMoved when any
/// sample since the previous frame, or the newest before it, had a forward speed above kStillSpeedMps;
/// kStoodStill when none did; kUnknown before the first sample, when the newest is more than max_age_s
/// older than the frame (the topic went quiet), or from the future (time went back: forgotten).
class StandstillDetector
{
public:
  static constexpr double kStillSpeedMps = 0.01;  ///< odometry noise of a standing base stays below 1 cm/s

  explicit StandstillDetector(double max_age_s = 1.0) : max_age_s_(max_age_s) {}
  /// A velocity sample: forward speed (m/s, either sign) at stamp_s (seconds, the frames' clock).
  void velocity(double linear_mps, double stamp_s);
  /// What the robot did since the previous call; starts the next interval. frame_s: the frame's stamp.
  RobotMotion sinceLastFrame(double frame_s);

private:
  double max_age_s_;
  bool have_sample_ = false;
  bool moved_since_frame_ = false;
  double latest_speed_mps_ = 0.0;
  double latest_s_ = 0.0;
};

/// What the localizer did with the frames missed before a frame (FrameClock; LocalizationResult::gap).
enum class FrameGap
{
  kNone,           ///< no frame was missed
  kFilledIn,       ///< each missed frame became a row without evidence (skipFrames)
  kSearchedAgain,  ///< at least K - 1 missed: the search started over from an empty window (skipFrames)
  kStoodStill,     ///< the frame shows the view of the last one before the gap: nothing filled in
  kNotFilledIn     ///< fill_frame_gaps is off
};

/// What the localizer says about one frame.
struct LocalizationResult
{
  LocalizationStatus status = LocalizationStatus::kInitializing;
  int keyframe = -1;            ///< matched keyframe index, -1 while there is no answer
  int64_t keyframe_stamp_ns = 0;///< source stamp of that keyframe
  double confidence = 0.0;      ///< in [0, 1]; thresholding it trades precision against recall
  double shift_px = 0.0;        ///< query content displaced this many px to the right of the keyframe's
  double homing_angle_rad = 0.0;///< turn to apply to get back onto the route; REP-103: positive = left
  bool query_informative = true;///< false for featureless (dark, blank) frames
  bool time_went_back = false;  ///< the stamp was before the last one: the localizer started over (reset)
  int missed_frames = 0;        ///< frames missed before this one, from the stamps (FrameClock)
  FrameGap gap = FrameGap::kNone;  ///< what was done with them
};

/// Running counts of the gaps the localizer reported (LocalizationResult::missed_frames and gap), as the
/// localizer nodelet's diagnostics and localize_offline's summary give them.
struct FrameGapCounts
{
  uint64_t gaps = 0;            ///< frames that came after a gap
  uint64_t missed_frames = 0;   ///< frames missed in the gaps that did not restart the search
  uint64_t searched_again = 0;  ///< gaps that restarted the search (FrameGap::kSearchedAgain)
  uint64_t stood_still = 0;     ///< gaps with the same view on both sides (FrameGap::kStoodStill)
  /// Frames missed in gaps no longer than the time the localizer spent on the frame before (whileBusy):
  /// those frames, if the camera sent them, came while it was busy and were replaced in a nodelet's input
  /// queue of 1.
  uint64_t missed_while_busy = 0;

  /// Whether a gap of `gap_s` with `missed` frames missed is of the localizer's own making, having spent
  /// `busy_s` on the frame before. With an input queue of 1 the frame taken next is the newest that came
  /// while it was busy, so such a gap is at most busy_s; one longer by more than half a frame period,
  /// gap_s / (missed + 1), had a frame that came after it was free and still never arrived: upstream.
  static bool whileBusy(double busy_s, double gap_s, int missed)
  {
    return missed > 0 && gap_s > 0.0 && busy_s >= gap_s - 0.5 * gap_s / (missed + 1);
  }

  void add(const LocalizationResult& result, bool while_busy = false)
  {
    if (result.missed_frames <= 0)
      return;
    if (while_busy && result.gap != FrameGap::kSearchedAgain)
      missed_while_busy += static_cast<uint64_t>(result.missed_frames);
    ++gaps;
    if (result.gap == FrameGap::kSearchedAgain)
      ++searched_again;
    else
      missed_frames += static_cast<uint64_t>(result.missed_frames);
    if (result.gap == FrameGap::kStoodStill)
      ++stood_still;
  }
};

/// Homing angle from an image shift: a scene displaced d px to the right means the camera yawed left,
/// so the correction is a right turn: angle = -atan(d / f), with f = (width / 2) / tan(hfov / 2) px.
double homingAngleFromShift(double shift_px, int image_width, double horizontal_fov_rad);

/// The probability of being within one keyframe for a margin confidence c in [0, 1]:
/// 1 / (1 + exp(-(offset + slope * c))); c itself when slope is 0 (no calibration).
double calibratedConfidence(double c, float offset, float slope);

/// Keyframes per frame of a DTW path (keyframe per row, oldest first) over its rows before the newest
/// (the newest row's end is the least settled): the mean over those rows, or, when the robot changed
/// speed lately, the speed over the last kRecentSpeedRows steps. "Changed" means that speed and the one
/// over the steps before them (at least kRecentSpeedRows too) differ by at least kSpeedChange keyframes
/// per frame. A robot stopping, halving or doubling its speed changes it by 0.5 or more; measured over 8
/// rows, one stop or skip more or less moves a speed by 0.125, so 0.4 leaves room for that. 1 (the
/// nominal speed) for fewer than three rows.
double pathSpeed(const std::vector<int>& path);
constexpr int kRecentSpeedRows = 8;
constexpr double kSpeedChange = 0.4;

/// The per-frame localizer. Not thread-safe: call from one thread (the nodelet's callback queue).
class Localizer
{
public:
  /// Throws std::invalid_argument for an empty map or invalid params.
  Localizer(std::shared_ptr<const RouteMap> map, const LocalizerParams& params);

  /// Applies new parameters between frames. Buffers are resized; the current match and status are
  /// kept when the sequence settings allow it; a change of `method` starts over (reset(); after the first
  /// frame from an unknown place, not start_keyframe). Throws std::invalid_argument for invalid params.
  void setParams(const LocalizerParams& params);
  /// Measures now, once per map and parameters, the map statistics the checks otherwise measure on the
  /// first check that needs them (the chance margins, chanceMargin: 20 x K whole-map rows, about 0.2 s for
  /// 1800 keyframes), so that no frame mid-run waits for them. The localizer nodelet and localize_offline
  /// call it after construction and after setParams; the answers are the same either way.
  void measureMapStatisticsNow();
  const LocalizerParams& params() const { return params_; }

  /// Processes one preprocessed image (CV_8UC1, the map's size). Throws std::invalid_argument otherwise.
  /// stamp_ns, the frame's stamp (0: unknown), tells the sequence apart from the frames' order: a stamp
  /// before the last one (a looping bag) starts over (reset), a gap in the stamps is frames missed
  /// (skipFrames, when fill_frame_gaps is set, unless the frame shows the view of the last one before the
  /// gap: the robot stood still). The result says which.
  /// motion: what the robot's odometry says it did since the previous frame. A featureless frame taken while
  /// the robot stood still (kStoodStill; e.g. stopped behind a vehicle or a person in front of the camera)
  /// changes nothing: no row, no step of any dead reckoning, the previous answer again. Without it the
  /// sequence goes on through featureless rows at the speed the robot had, and a robot stopped behind an
  /// occluder would be left behind by its own track.
  LocalizationResult process(const cv::Mat& preprocessed, int64_t stamp_ns = 0,
                             RobotMotion motion = RobotMotion::kUnknown);

  /// Tells the localizer that the camera missed `count` frames since the last one (a dropout, frames
  /// dropped on the way; FrameClock measures it from the stamps). Each becomes a row without evidence, as
  /// a featureless frame is, so the sequence goes on through the gap at any speed the DTW allows and the
  /// frames after it tell where the robot went. A gap of K - 1 frames or more (K: ring_buffer_rows, or the
  /// baseline's sequence length) leaves the frame after it no row from before it in the window: the track
  /// is lost and the search starts over from an empty window.
  void skipFrames(int count);

  /// Forgets the sequence (e.g. time jumped back); the next frames initialize globally. The frame period
  /// learnt from the stamps is kept.
  void reset();
  /// Forgets the sequence as reset() does; the next frames start as start(from_start_keyframe) says.
  void reset(bool from_start_keyframe);

  const RouteMap& map() const { return *map_; }
  const CostRingBuffer& costs() const { return ring_; }
  /// Best path of the last frame, one keyframe per ring-buffer row, oldest first; empty after a frame
  /// that searched the whole map (initializing, lost).
  const std::vector<int>& lastPath() const { return last_path_; }
  /// The robot's cruise speed in keyframes per frame (cruise_speed_frames): 1 until a track is followed.
  double cruiseSpeed() const { return cruise_.speed; }
  /// Frames processed since construction or reset().
  uint64_t frameCount() const { return frames_; }
  /// Median textureEnergy of the map's keyframes, and the featureless threshold derived from it.
  float medianKeyframeEnergy() const { return map_stats_.median_energy; }
  float minTextureEnergy() const { return map_stats_.min_texture_energy; }
  /// Median mean absolute byte difference between consecutive keyframes, and the stationary threshold.
  float medianKeyframeChange() const { return map_stats_.median_change; }
  float stationaryChange() const { return map_stats_.stationary_change; }
  /// Whether global searches compare halved images on this map (coarse_search_keyframes).
  bool coarseGlobalSearch() const { return coarse_difference_ != nullptr; }
  /// [rows]: the chance margin over that many rows (chanceMargin), 1 to max(K, relocalization_rows); empty
  /// until measured (measureMapStatisticsNow, or the first check that needs it).
  const std::vector<float>& chanceMargins() const { return map_stats_.chance_margins; }

  /// The paper's figure 4 (debug_image.h) for keyframes [first, first + width), scale px per cell, with
  /// the last path, match and status (no confidence: the localizer nodelet renders with its result's). BGR8.
  cv::Mat renderDebugImage(int first_keyframe, int width, int scale = 4) const;

private:
  /// The estimator's state (doc/design.md, section 2, has the diagram). Published as status(): kCoasting as
  /// tracking, a tracked match within end_of_route_keyframes of the map's end as end of route, and a
  /// coasting frame whose check found another place (trackContradicted) as lost.
  enum class State
  {
    kInitializing,  ///< no place yet: global search until one is confirmed (searchStep)
    kTracking,      ///< following the route in a band around the last match (trackStep)
    kCoasting,      ///< tracking on weak evidence: dead-reckoned, each frame checked for another place (coastStep)
    kLost           ///< the track was lost: global search until a place is confirmed (searchStep)
  };
  /// The only change of state_ after start(): enters `next` with what it needs. place >= 0 (kTracking): a
  /// place was confirmed (global search, startRefuted, the checks while coasting) and a new track starts
  /// there; -1: the track goes on (coasting ended by a confident frame, the baseline's first answer).
  void transition(State next, int place = -1);
  /// The published status of state_ and last_match_.
  LocalizationStatus status() const;

  /// One frame's inputs and what step() decided on it; lives for one step() only.
  struct Frame
  {
    const uint8_t* query = nullptr;  // nullptr: a frame the camera missed
    float energy = 0.0f;             // textureEnergy of the query
    bool informative = false;        // not featureless (min_texture_ratio)
    bool repeated = false;           // shows the view of the last query (repeatsLastView)
    bool tracking = false;           // the state was kTracking or kCoasting when the frame came
    bool global = false;             // its match is searched over the whole map (searching, or the baseline)
    bool checking_start = false;     // a known start is being checked (its row covers the whole map)
    bool first_from_start = false;   // the first frame since a known start
    int first = 0, width = 0;        // keyframes of its row (tracking: the band)
    int reach_first = 0, reach_width = 0;  // keyframes its match may end at (lost, !detect_kidnapping: reachable)
    int predicted = 0;               // keyframe predicted while tracking: one ahead of the last match
    bool relocated = false;          // the track moved to another place on this frame (no speed sample)
    bool borne_out = false;          // a confident answer on a place not only assumed: the speed is kept
    bool moved_by_check = false;     // ... by the checks of recentCheck or coastStep (moveTrackOnConfirmation)
    bool contradicted = false;       // this frame's check (coasting, recentCheck) found another place: lost
  };
  /// One frame of process(), or a frame the camera missed (query nullptr: a featureless row, skipFrames):
  /// the frame's row, its sequence match, the handler of the state it came in, the result. energy: the
  /// query's textureEnergy (0 for nullptr), computed once per frame by process().
  LocalizationResult step(const uint8_t* query, float energy);
  /// What the query is (texture, a repeated view) and where its row goes (band, global, the start's check).
  Frame beginFrame(const uint8_t* query, float energy);
  /// Appends the frame's row to the ring buffer (first the recent queries' after a loss) and keeps the
  /// query among the recent ones.
  void appendRow(const Frame& frame);
  /// The sequence match over the window: the DTW (band or whole map), or the baseline; last_path_ is set.
  SequenceMatch matchSequence(const Frame& frame);
  /// While a known start is checked: startRefuted moves the track (and *match) to the confirmed place,
  /// unless the images confirm the track (confirmable as a global answer, and newestRowsSupport).
  void checkStart(Frame* frame, SequenceMatch* match);
  /// kInitializing, kLost: the global answer, once confirmed, starts a track.
  void searchStep(const Frame& frame, const SequenceMatch& match, bool confirmable);
  /// kTracking, kCoasting: loss detection; lost, or coasting (loss_needs_contradiction), or on.
  void trackStep(Frame* frame, SequenceMatch* match, bool confident);
  /// kCoasting: the check for another place (trackContradicted), confirmed -> moveTrackOnConfirmation; else the answer
  /// is the dead-reckoned coasting_.position.
  void coastStep(Frame* frame, SequenceMatch* match, bool check_started);
  /// kTracking, on a new view: when the newest relocalization_rows rows alone do not support the track's end
  /// (its confidence over them below confidence_threshold), they are compared with the whole map
  /// (trackContradicted), and so is each new view while the check goes on: over the check's own frames (at
  /// least relocalization_rows) and over every frame it holds (its window growing to K rows);
  /// once init_confirm_frames such checks in a row found the same place moving as the
  /// robot can, the track moves there (moveTrackOnConfirmation). The whole window, K rows, lags K / 2 frames behind a
  /// robot that was carried elsewhere; its newest rows do not. The newest rows' support ends a check, but one
  /// that has found the track contradicted only once they also end at the track over the whole map
  /// (newestRowsEndAt): the band alone can hold a look-alike of the old place.
  void recentCheck(Frame* frame, SequenceMatch* match);
  /// Still tracking after the handler: the cruise speed's sample and the last match.
  void followTrack(const Frame& frame, int keyframe);
  /// The result of the frame: keyframe (contradicted: the place that contradicts, coasting or beating the
  /// track by more than contradiction_margin_share of chanceMargin; lost: the global search's guess or,
  /// dead_reckon_while_lost, the dead-reckoned keyframe), confidence (0 while lost or contradicted), status,
  /// homing.
  /// Step 5: the posterior moves on one frame and weighs its evidence (posterior_row_).
  void updatePosterior();
  LocalizationResult publish(const Frame& frame, int keyframe, double confidence);

  /// The query shows the view of the last one that entered the ring buffer (stationary_ratio): the
  /// camera stood still. False for nullptr.
  bool repeatsLastView(const uint8_t* query) const;
  /// Whether a query of that textureEnergy has texture enough to tell anything (>= min_texture_energy):
  /// not featureless.
  bool textured(float energy) const { return energy >= map_stats_.min_texture_energy; }
  /// Status after construction or reset(): tracking from start_keyframe, or initializing.
  void start();
  /// start(), or with from_start_keyframe false initializing whatever start_keyframe says (mid-drive).
  void start(bool from_start_keyframe);
  /// While a known start (start_keyframe) is checked (the first K new views): the global search over the
  /// same rows (*elsewhere, no start) confirmed a place other than the track's (`track`), one the robot
  /// could have driven to (max_step keyframes a frame) from the check's first global answer: the robot did
  /// not start where it was told. A place confirmed after the answers went through other places first (a
  /// robot beside its start, turning onto the route, fits look-alikes in turn) does not refute the start.
  bool startRefuted(const SequenceMatch& track, bool informative, SequenceMatch* elsewhere);
  /// The share of a full window's evidence a match has seen: its distinct views / K, at most 1.
  double evidenceShare(const SequenceMatch& match) const;
  /// 1 - exp(-margin * evidence / confidence_scale), the margin being over the best path ending at
  /// another keyframe (other_place false) or at another place (true, SequenceMatch::second_place_cost).
  double matchConfidence(const SequenceMatch& match, bool other_place, double evidence) const;
  /// Rows the sequence match looks at: K (ring_buffer_rows), or the baseline's sequence length.
  int windowRows() const;
  /// Whether skipFrames(count) starts the search over: the frame after the gap would find no row from
  /// before it in the window.
  bool gapRestartsTheSearch(int count) const { return count >= windowRows() - 1; }
  void rebuildComparators();
  /// First image row compared in the map's images (the free function of that name).
  int firstComparedRow() const;
  /// The keyframe to report for a DTW match `dtw_keyframe` while tracking: inside a run of near-identical
  /// keyframes (the teach camera stood still, or saw nothing) the DTW cannot tell them apart, so the
  /// answer moves through the run at the speed the path had when it entered (pathSpeed, run_dead_reckoning).
  int keyframeThroughRun(int dtw_keyframe);
  /// Keyframe k lies in a run of more than one near-identical keyframe (a station, or a featureless stretch).
  bool inRunOfCopies(int k) const { return map_stats_.run_first[k] != map_stats_.run_last[k]; }
  /// The motion prior of the match while tracking: the robot is predicted at the last match plus the
  /// speed of the last path (pathSpeed), or at the last match itself when the query repeats the last
  /// view (the camera stood still) outside a run of identical keyframes; then only ends ahead of it pay
  /// (the robot has not moved on, but a step back corrects an answer that ran on past the stop).
  /// Inside such a run both teach and repeat stood still, and the robot goes on through it at the speed
  /// it came. For a new view only once the track has been followed for K frames (tracked_frames_); none
  /// (weight 0) before.
  EndPrior motionPrior(bool repeated_query) const;
  /// The robot's speed along the map, keyframes per frame: pathSpeed of the last path, in [0, max_step].
  /// Run dead reckoning and the motion prior both predict with it.
  double trackSpeed() const;

  /// Appends the eq. 2 row of keyframes [first, first + width); `global`: a global search (coarse on big maps).
  void computeRow(const uint8_t* query, float query_energy, bool query_informative, bool repeated_query, bool global,
                  int first, int width, CostRingBuffer* target = nullptr);
  /// Whether the newest relocalization_rows rows alone, as a path over the frame's band ending at the track's
  /// keyframe, confirm it (its place confidence over them at least confidence_threshold): then no check
  /// weighs another place (recentCheck, checkStart). False while the window holds fewer rows.
  bool newestRowsSupport(const Frame& frame, int track_keyframe);
  /// Whether the newest relocalization_rows rows of a check's whole-map window (recentCheck), as a path over
  /// the whole map, end at `place` (within the exclusion radius, in runs).
  bool newestRowsEndAt(const CostRingBuffer& check, int place);
  /// Whether keyframes a and b are one place: within the exclusion radius, counted in runs (copies of one
  /// view are one run).
  bool samePlace(int a, int b) const;
  /// A check of the track at `track_keyframe` (recentCheck, coastStep): whether the newest `rows` rows of the
  /// check's whole-map window (extendCheck), compared with the whole map as a sequence, end at another
  /// place (farther than the exclusion radius, in runs) that is confidently better than every other place
  /// and than the track's end ([track - exclusion_radius, track + max_step + max_jump_ahead]) by a margin
  /// mapping to at least confidence_threshold (matchConfidence, the evidence being the distinct views
  /// among those rows over K). Weak evidence (no place stands out) is not contrary evidence.
  /// While coasting, a sequence that ends next to the dead-reckoned keyframe (within the exclusion radius),
  /// or where the robot can have driven since the last confident answer (forward, at most max_step a frame,
  /// give or take the exclusion radius) and beats the dead-reckoned end ([reckoned - exclusion_radius,
  /// reckoned + exclusion_radius]) by more than chanceMargin, is no contradiction: the images place it there,
  /// and coast_fix_ says where (coastStep moves the dead reckoning to it).
  /// The rows weighed: the newest `rows` of `ring` (extendCheck).
  bool trackContradicted(int track_keyframe, const CostRingBuffer& ring, int rows);
  /// A check's whole-map rows of the newest `window` recent queries, kept in `ring` (coasting: K rows in
  /// coasting_.ring; recentCheck: K rows in newest_check_.ring, the check's window growing to them). new_rows: the
  /// check goes on, the newest new_rows frames (those since its last row) are new; 0: it starts afresh.
  void extendCheck(int new_rows, int window, CostRingBuffer* ring);
  /// The keyframes a robot that only moves as it drives (detect_kidnapping false) can be at `frames` frames
  /// after the images placed it at `anchor` (a lost track's last answer; coasting: the last confident one):
  /// [*first, *first + *width). The ends of the match after a loss and of the checks while coasting.
  /// `slack`: keyframes of doubt about the anchor, behind and ahead (-1: search_radius, the track may have run
  /// ahead of where the images last placed it; the checks while coasting: exclusion_radius).
  void reachableEnds(double anchor, int64_t frames, int* first, int* width, int slack = -1) const;
  /// The cheapest end of the last DTW match (over [first, first + width)) at the track's place,
  /// [track - exclusion_radius, track + ahead]: a track may jump max_step + max_jump_ahead ahead; a
  /// dead-reckoned keyframe is only as sure as the exclusion radius around it.
  float trackEndCost(int track_keyframe, int ahead, int first, int width) const;
  /// How much cheaper per row, by chance, the best path at a wrong place of this map is than a stretch of
  /// track-sized ends at another wrong place, over `rows` rows: measured once per map and parameters on
  /// kChanceWindows stretches of the map's own keyframes taken as queries, their true places left out (the
  /// largest margin seen). trackContradicted needs more than contradiction_margin_share of it to contradict
  /// the track (0: no such test), and a contradicted frame while tracking publishes that place only then.
  float chanceMargin(int rows);
  /// map_stats_.chance_margins for every window of 1 to max(K, relocalization_rows) rows, in one pass.
  void measureChanceMargins();
  /// Whether any check weighs a contradiction against chanceMargin with these parameters (then
  /// measureMapStatisticsNow measures it).
  bool checksAgainstChance() const;
  static constexpr int kChanceWindows = 20;
  /// Lost from the track at `track_position` (keyframes): transition(kLost) clears the ring buffer (its rows
  /// covered only the track's band) and the dead-reckoned answer goes on from there at coastSpeed()
  /// (dead_reckon_while_lost). Also for a gap that restarts the search (skipFrames).
  void loseTrack(double track_position);
  /// One more check (coasting, or recentCheck) for `confirmation`, its verdict in frame->contradicted. Once
  /// init_confirm_frames checks confirmed contradicting_place_, the track moves there (transition(kTracking,
  /// place)), the check's whole-map rows becoming the ring buffer's, and *match and *frame say so: true.
  bool moveTrackOnConfirmation(GlobalConfirmation* confirmation, bool informative, const CostRingBuffer& check,
                               Frame* frame, SequenceMatch* match);
  /// Appends to `target` the whole-map rows of the newest `count` (at most recent_count_) recent queries,
  /// oldest first: a global search after a loss, and trackContradicted's check.
  void replayRecentQueries(int count, CostRingBuffer* target);
  /// Keyframes per frame dead reckoning moves on at: the cruise speed, in [0, max_step].
  double coastSpeed() const;
  /// Where dead reckoning puts the robot this frame while the window holds no evidence: the last
  /// dead-reckoned position (or the last answer) plus coastSpeed().
  double reckonedPosition(bool first_from_start) const;
  /// `position` moved on by `frames` frames at coastSpeed(), at most the last keyframe: every dead reckoning.
  double reckonedAhead(double position, double frames = 1.0) const;

  std::shared_ptr<const RouteMap> map_;
  LocalizerParams params_;
  std::unique_ptr<ImageDifference> difference_;
  std::unique_ptr<HomingEstimator> homing_;  // the reported shift of the matched keyframe (homing.h)
  std::unique_ptr<CensusDifference> census_difference_;
  std::unique_ptr<ImageDifference> coarse_difference_;  // global search on halved images (or none)
  std::vector<uint8_t> coarse_keyframes_;              // halveImage of every keyframe, contiguous
  std::vector<uint8_t> coarse_query_;
  std::vector<uint8_t> keyframe_census_;   // census codes of all keyframes, when that cost is used
  std::vector<uint8_t> query_census_;
  double reckon_position_ = -1.0;          // dead-reckoned position while the window ties; < 0: not
  double run_position_ = -1.0;             // reported position inside the current run; < 0: not in one
  double run_velocity_ = 0.0;              // keyframes per frame when the current run was entered
  ContrastRunsScratch contrast_scratch_;
  /// What this map is like, measured once per map (measureMap), the keyframes' classes once per
  /// min_texture_ratio and stationary_ratio (classifyKeyframes), the chance margin once per map and
  /// sequence settings (chanceMargin).
  struct MapStatistics
  {
    float median_energy = 0.0f;          // of the keyframes' textureEnergy
    std::vector<float> change;           // [k]: mean |byte difference| of keyframes k - 1 and k ([0] = 0)
    float median_change = 0.0f;          // its median
    float texture_ratio = -1.0f;         // the min_texture_ratio and stationary_ratio classified for (-1: none)
    float stationary_ratio = -1.0f;
    float min_texture_energy = 0.0f;     // min_texture_ratio * median_energy
    float stationary_change = 0.0f;      // stationary_ratio * median_change
    std::vector<uint8_t> informative;    // [k]: keyframe k has texture (min_texture_energy)
    std::vector<uint8_t> repeats;        // [k]: keyframe k shows the view of the informative one before it
    std::vector<int> run;                // [k]: number of keyframes up to k that are not repeats
    std::vector<int> run_first, run_last;  // [k]: first and last keyframe of k's run (k itself if alone)
    std::vector<float> chance_margins;   // [rows]: chanceMargin over that many rows (empty: not yet measured)
  };
  /// The map-only part of map_stats_ (medians, keyframe changes), on construction.
  void measureMap(bool parallel);
  /// The keyframes' classes in map_stats_ (informative, repeats, runs), when the ratios changed.
  void classifyKeyframes();
  MapStatistics map_stats_;
  CostRingBuffer ring_;
  OnlineDtw dtw_;

  // per-frame scratch, sized once per map / parameter change
  std::vector<float> raw_costs_, shifts_;              // indexed by keyframe: computeRow's scratch
  std::vector<uint8_t> mask_;                          // informative entries of the newest band
  RoutePosterior posterior_;                           // the published confidence (posterior_confidence)
  /// The frame's costs for the posterior: the widest row computed for it (appendRow, replayRecentQueries).
  struct PosteriorRow
  {
    std::vector<float> costs;
    std::vector<uint8_t> usable;
    int first = 0, width = 0;
    bool has_evidence = false;          ///< an informative query
    bool newest_is_this_frame = false;  ///< the newest recent query is this frame's (replays reach it)
    void keep(const float* row_costs, const uint8_t* row_usable, int row_first, int row_width);
  };
  PosteriorRow posterior_row_;
  cv::Mat query_copy_;                                 // only for non-continuous input

  State state_ = State::kInitializing;
  int last_match_ = -1;
  /// A known start (start_keyframe) and its check (checkStart, startRefuted): set by begin() in start(), the
  /// check on until K new views have come (beginFrame), the state changes to another place or to kLost, or a
  /// gap restarts the search (skipFrames).
  struct KnownStart
  {
    int keyframe = -1;           // the start keyframe
    bool checking = false;       // the start is being checked
    int rows = 0;                // rows appended since the start (0: no frame answered yet)
    int views = 0;               // of them, informative new views
    int first_answer = -1;       // the global search's first answer during the check (-1: none yet)
    int first_answer_row = 0;    // `rows` at that answer
    void begin(int start_keyframe);
  };
  KnownStart start_;
  int tracked_frames_ = 0;               // frames answered since tracking last started
  struct CruiseSpeed
  {
    double speed = 1.0;  // keyframes per frame: the mean of `samples` samples
    int samples = 1;     // the nominal speed counts as the first
  };
  CruiseSpeed cruise_;
  CruiseSpeed confirmed_cruise_;         // cruise_ at the last confident answer (Frame::borne_out)
  GlobalConfirmation confirmation_;
  LossDetector loss_;
  FrameClock clock_;
  uint64_t frames_ = 0;
  std::vector<int> last_path_;
  LocalizationResult last_result_;         // the last frame's (answered again for a frame that changes nothing)
  cv::Mat entered_query_;                  // the last query that entered the ring buffer (empty: none)
  /// The last relocalization_rows queries, oldest first from `next` (a ring), with what computeRow needs.
  struct RecentQuery
  {
    std::vector<uint8_t> image;
    float energy = 0.0f;
    bool informative = false, repeated = false;
  };
  std::vector<RecentQuery> recent_queries_;
  int recent_count_ = 0, recent_next_ = 0;
  /// recentCheck's state: a check of the newest frames against the whole map, under way from the first new
  /// view whose newest frames do not support the track until they do again or it moves the track; end()
  /// leaves nothing of it set (the ring aside: extendCheck starts it afresh), called then and on every
  /// change of state (transition, start). After as many checks as the window has rows found no place
  /// elsewhere it rests instead (under_way false, `unanswered` kept) until the newest frames support the
  /// track again.
  struct NewestFramesCheck
  {
    CostRingBuffer ring;               // whole-map rows of the newest queries (its window: extendCheck)
    bool under_way = false;            // the last new view was checked against the whole map
    bool contradicted = false;         // and that check found the track contradicted
    bool found_contradiction = false;  // some check since it began found the track contradicted
    int unanswered = 0;                // checks in a row that found no place elsewhere
    int pending = 0;                   // frames since its last row (featureless, repeated, missed)
    int own_rows = 0;                  // rows since it began, its first frame's included
    GlobalConfirmation confirmation;   // its verdicts: another place, confirmed
    void end();
  };
  NewestFramesCheck newest_check_;
  /// kCoasting's own state, set on entering it (begin, from transition; the ring by the first check,
  /// extendCheck) and used only while in it: the dead reckoning and its check of the recent frames against
  /// the whole map (coastStep).
  struct Coasting
  {
    double position = 0.0;             // the dead-reckoned keyframe
    CostRingBuffer ring;               // the check's whole-map rows of the recent queries
    int pending = 0;                   // missed frames since the check's last row
    GlobalConfirmation confirmation;   // the checks' verdicts: another place, confirmed
    void begin(double from);
  };
  Coasting coasting_;
  int contradicting_place_ = -1;         // the place the last trackContradicted found
  bool contradiction_beats_chance_ = false;  // ... by more than contradiction_margin_share of chanceMargin
  double contradicting_confidence_ = 0.0;  // its margin confidence (matchConfidence, before calibration)
  int coast_fix_ = -1;                   // where the last trackContradicted placed the robot instead (or -1)
  int last_confident_ = -1;              // the last confident, informative answer while tracking
  int frames_since_confident_ = 0;
  double lost_position_ = -1.0;          // dead-reckoned keyframe while lost (< 0: none, no track to go on)
  double lost_anchor_ = -1.0;            // where the track was lost (< 0: none), for the reachable band
  int64_t lost_frame_ = 0;               // frames_ when it was lost (less the frames a gap missed since)
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_LOCALIZER_H
