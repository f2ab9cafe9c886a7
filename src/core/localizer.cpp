#include "along_route_localization/localizer.h"

#include "along_route_localization/debug_image.h"
#include "along_route_localization/parameters.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace along_route_localization
{

std::string toString(LocalizationStatus status)
{
  switch (status)
  {
    case LocalizationStatus::kInitializing:
      return "initializing";
    case LocalizationStatus::kTracking:
      return "tracking";
    case LocalizationStatus::kLost:
      return "lost";
    case LocalizationStatus::kEndOfRoute:
      return "end_of_route";
  }
  return "unknown";
}

std::string toString(SequenceMethod method)
{
  return method == SequenceMethod::kSeqSlam ? "seqslam" : "dtw";
}

bool sequenceMethodFromString(const std::string& name, SequenceMethod* method)
{
  if (name == "dtw")
    *method = SequenceMethod::kOnlineDtw;
  else if (name == "seqslam")
    *method = SequenceMethod::kSeqSlam;
  else
    return false;
  return true;
}

std::string LocalizerParams::validate() const
{
  // The working range of each parameter given by name is the table's; the rest are combinations and
  // fields set only in code.
  ParameterSet set;
  set.localizer = *this;
  const std::string out_of_range = checkRanges(ParameterGroup::kLocalizer, set);
  if (!out_of_range.empty())
    return out_of_range;
  std::ostringstream e;
  if (!std::isfinite(contrast_clamp + row_weight_reference + row_weight_range + min_texture_ratio +
                     stationary_ratio + motion_prior_weight + motion_prior_cap + confidence_scale) ||
      !std::isfinite(confidence_threshold + horizontal_fov_rad))
    e << "every parameter must be a finite number";
  else if (!(dtw.move_penalty >= 0.0f) || !std::isfinite(dtw.move_penalty))
    e << "move_penalty must be finite and >= 0, got " << dtw.move_penalty;
  else if (!std::isfinite(seqslam.missing_cost))
    e << "seqslam missing_cost must be finite";
  else if (!(seqslam.min_velocity <= seqslam.max_velocity))
    e << "seqslam_min_velocity (" << seqslam.min_velocity << ") must not exceed seqslam_max_velocity ("
      << seqslam.max_velocity << ")";
  else if ((seqslam.max_velocity - seqslam.min_velocity) / seqslam.velocity_step > 1000.0f)
    e << "seqslam velocities must be at most 1000 steps apart, got " << seqslam.min_velocity << " to "
      << seqslam.max_velocity << " by " << seqslam.velocity_step;
  else if (seqslam.exclusion_radius < 0)
    e << "seqslam exclusion_radius must be >= 0, got " << seqslam.exclusion_radius;
  else if (shift_bands > 1 && cost_function != CostFunction::kSad)
    e << "shift_bands " << shift_bands << " needs cost_function sad (the census cost takes one shift)";
  else if (max_vertical_shift_px > 0 && cost_function != CostFunction::kSad)
    e << "max_vertical_shift_px " << max_vertical_shift_px << " needs cost_function sad (the census cost compares "
      << "level images only)";
  else if (ring_buffer_rows < min_init_frames)
    // A global search answers from the min_init_frames-th row on; the window would never hold that many,
    // and a track once lost would stay lost (Nordland, K = 4 and min_init_frames 5: lost from frame 22 on).
    e << "ring_buffer_rows (" << ring_buffer_rows << ") must be at least min_init_frames (" << min_init_frames
      << "): a global search would never answer";
  else if (lost_after_frames > lost_window_frames)
    e << "lost_after_frames must be in [1, lost_window_frames = " << lost_window_frames << "], got "
      << lost_after_frames;
  return e.str();
}

std::string LocalizerParams::validateForImages(const PreprocessingParams& images) const
{
  const int width = images.output_width;
  const int compared_rows = images.output_height - along_route_localization::firstComparedRow(images);
  if (2 * max_shift_px >= width)
    return "max_shift_px must be below half the image width (at most " + std::to_string((width - 1) / 2) +
           " for " + std::to_string(width) + " px)";
  if (shift_bands > compared_rows)
    return "shift_bands must be at most the compared rows (" + std::to_string(compared_rows) + "), got " +
           std::to_string(shift_bands);
  if (2 * max_vertical_shift_px >= compared_rows)
    return "max_vertical_shift_px must be below half the compared rows (" + std::to_string(compared_rows) +
           "), got " + std::to_string(max_vertical_shift_px);
  return std::string();
}

namespace
{

/// Mean absolute difference of two images of the map's size over rows [first_row, height).
float meanAbsoluteDifference(const uint8_t* a, const uint8_t* b, int width, int height, int first_row)
{
  const int rows = height - first_row;
  if (rows <= 0)
    return 0.0f;
  // A plain loop (vectorized by the compiler): run once per keyframe when a map is loaded, where
  // cv::norm's per-call set-up cost more than the 2 KB it reads.
  uint64_t sum = 0;
  for (int y = first_row; y < height; ++y)
  {
    const uint8_t* row_a = a + static_cast<size_t>(y) * width;
    const uint8_t* row_b = b + static_cast<size_t>(y) * width;
    uint32_t row_sum = 0;  // at most 255 * width
    for (int x = 0; x < width; ++x)
      row_sum += static_cast<uint32_t>(std::abs(row_a[x] - row_b[x]));
    sum += row_sum;
  }
  return static_cast<float>(static_cast<double>(sum) / (static_cast<double>(rows) * width));
}

/// f(k) for every keyframe k, split across cores for big maps (set-up work done once per map).
template <typename F>
void forEachKeyframe(size_t count, bool parallel, const F& f)
{
  const auto run = [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k)
      f(k);
  };
  if (parallel && count >= 4096)
    cv::parallel_for_(cv::Range(0, static_cast<int>(count)), run, std::max(1.0, count / 1024.0));
  else
    run(cv::Range(0, static_cast<int>(count)));
}

float median(std::vector<float> values)
{
  if (values.empty())
    return 0.0f;
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

}  // namespace

double homingAngleFromShift(double shift_px, int image_width, double horizontal_fov_rad)
{
  const double focal_px = 0.5 * image_width / std::tan(0.5 * horizontal_fov_rad);
  return -std::atan(shift_px / focal_px);
}

double calibratedConfidence(double c, float offset, float slope)
{
  if (slope == 0.0f)
    return c;
  return 1.0 / (1.0 + std::exp(-(static_cast<double>(offset) + static_cast<double>(slope) * c)));
}

double pathSpeed(const std::vector<int>& path)
{
  const int last = static_cast<int>(path.size()) - 2;  // the row before the newest
  if (last < 1)
    return 1.0;
  const double mean = static_cast<double>(path[last] - path[0]) / last;
  const int split = last - kRecentSpeedRows;  // older rows [0, split], recent rows [split, last]
  if (split < kRecentSpeedRows)
    return mean;
  const double older = static_cast<double>(path[split] - path[0]) / split;
  const double recent = static_cast<double>(path[last] - path[split]) / kRecentSpeedRows;
  return std::abs(recent - older) >= kSpeedChange ? recent : mean;
}

Localizer::Localizer(std::shared_ptr<const RouteMap> map, const LocalizerParams& params) : map_(std::move(map))
{
  if (!map_ || map_->empty())
    throw std::invalid_argument("Localizer: the route map is empty");
  measureMap(params.parallel);
  setParams(params);
  const size_t n = map_->size();
  raw_costs_.resize(n);
  shifts_.resize(n);
  mask_.resize(n);
  start();
}

void Localizer::start()
{
  start(true);
}

void Localizer::start(bool from_start_keyframe)
{
  state_ = State::kInitializing;  // the initial state: nothing to leave, so not a transition
  last_match_ = -1;
  lost_position_ = lost_anchor_ = -1.0;
  last_confident_ = -1;
  frames_since_confident_ = 0;
  newest_check_.end();
  const bool known_start =
      from_start_keyframe && params_.start_keyframe >= 0 && params_.method == SequenceMethod::kOnlineDtw;
  start_.begin(known_start ? params_.start_keyframe : -1);
  posterior_.reset(static_cast<int>(map_->size()), start_.keyframe);
  if (!known_start)
    return;
  state_ = State::kTracking;
  last_match_ = start_.keyframe;
}

void Localizer::KnownStart::begin(int start_keyframe)
{
  keyframe = start_keyframe;
  checking = start_keyframe >= 0;
  rows = views = 0;
  first_answer = -1;
  first_answer_row = 0;
}

void Localizer::setParams(const LocalizerParams& params)
{
  std::string invalid = params.validate();
  if (invalid.empty())
    invalid = params.validateForImages(map_->params());
  if (invalid.empty() && params.start_keyframe >= static_cast<int>(map_->size()))
    invalid = "start_keyframe must be below the map's " + std::to_string(map_->size()) + " keyframes, got " +
              std::to_string(params.start_keyframe) + " (-1: unknown, search the whole map)";
  if (!invalid.empty())
    throw std::invalid_argument("invalid localizer parameters: " + invalid);
  const bool method_changed = params.method != params_.method;
  const bool comparators_changed = !difference_ || params.max_shift_px != params_.max_shift_px ||
                                   params.shift_bands != params_.shift_bands ||
                                   params.max_vertical_shift_px != params_.max_vertical_shift_px ||
                                   params.subpixel_shift != params_.subpixel_shift ||
                                   params.cost_function != params_.cost_function ||
                                   params.coarse_search_keyframes != params_.coarse_search_keyframes ||
                                   params.homing_max_shift_px != params_.homing_max_shift_px ||
                                   params.homing_max_vertical_shift_px != params_.homing_max_vertical_shift_px;
  params_ = params;
  dtw_.setParams(params_.dtw);
  dtw_.setParallel(params_.parallel);
  PosteriorParams posterior = params_.posterior;
  posterior.max_step = params_.dtw.max_step;
  posterior_.setParams(posterior);
  confirmation_.configure(params_.init_confirm_frames, params_.dtw.max_step);
  coasting_.confirmation.configure(params_.init_confirm_frames, params_.dtw.max_step);
  newest_check_.confirmation.configure(params_.init_confirm_frames, params_.dtw.max_step);
  loss_.configure(params_.lost_after_frames, params_.lost_window_frames);
  const int rows = std::max(params_.ring_buffer_rows,
                            params_.method == SequenceMethod::kSeqSlam ? params_.seqslam.sequence_length : 0);
  ring_.resize(rows, static_cast<int>(map_->size()));
  if (params_.min_texture_ratio != map_stats_.texture_ratio || params_.stationary_ratio != map_stats_.stationary_ratio)
    classifyKeyframes();
  run_position_ = -1.0;
  if (static_cast<int>(recent_queries_.size()) != params_.relocalization_rows)
  {
    recent_queries_.assign(params_.relocalization_rows, RecentQuery());
    for (RecentQuery& recent : recent_queries_)
      recent.image.resize(map_->keyframeBytes());
    recent_count_ = recent_next_ = 0;
  }
  if (comparators_changed)
    rebuildComparators();
  map_stats_.chance_margins.clear();  // chanceMargin depends on the comparison, eq. 2, the DTW and K
  if (method_changed)
  {
    // The other method starts over: the baseline has no lost state to leave, nor the DTW's track. Mid-drive
    // from an unknown place (a global search), not at start_keyframe: the robot is somewhere along the route.
    reset(frames_ == 0);
  }
}

void Localizer::measureMapStatisticsNow()
{
  if (checksAgainstChance() && map_stats_.chance_margins.empty())
    measureChanceMargins();
}

bool Localizer::checksAgainstChance() const
{
  // The two callers of trackContradicted: recentCheck weighs a contradiction against chance, a check while
  // coasting the place it found against the reckoned one, and a contradiction too.
  const bool dtw = params_.method == SequenceMethod::kOnlineDtw;
  const bool recent_check =
      params_.detect_kidnapping && dtw && std::min(params_.relocalization_rows, params_.ring_buffer_rows) > 0;
  return recent_check || (dtw && params_.loss_needs_contradiction);
}

void Localizer::measureMap(bool parallel)
{
  // Properties of the map alone: what a normal keyframe's texture is, and how much consecutive keyframes
  // differ while the teach camera moved.
  MapStatistics& stats = map_stats_;
  std::vector<float> values(map_->size());
  for (size_t k = 0; k < map_->size(); ++k)
    values[k] = map_->energy(k);
  stats.median_energy = median(values);
  const int sky = firstComparedRow();
  stats.change.assign(map_->size(), 0.0f);
  forEachKeyframe(map_->size(), parallel, [&](int k) {
    if (k > 0)
      stats.change[k] =
          meanAbsoluteDifference(map_->keyframe(k - 1), map_->keyframe(k), map_->width(), map_->height(), sky);
  });
  stats.median_change = median(std::vector<float>(stats.change.begin() + 1, stats.change.end()));
}

void Localizer::classifyKeyframes()
{
  MapStatistics& stats = map_stats_;
  stats.texture_ratio = params_.min_texture_ratio;
  stats.stationary_ratio = params_.stationary_ratio;
  stats.min_texture_energy = params_.min_texture_ratio * stats.median_energy;
  stats.stationary_change = params_.stationary_ratio * stats.median_change;
  const int n = static_cast<int>(map_->size());
  stats.informative.resize(n);
  for (int k = 0; k < n; ++k)
    stats.informative[k] = map_->energy(k) >= stats.min_texture_energy ? 1 : 0;
  // A featureless keyframe shows no view: it neither starts nor ends a run (it joins the run before it).
  // An informative keyframe repeats the view of the last informative keyframe before it, or not.
  stats.repeats.assign(n, 0);
  const int sky = firstComparedRow();
  int last_informative = stats.informative[0] ? 0 : -1;
  for (int k = 1; k < n; ++k)
  {
    if (!stats.informative[k])
    {
      stats.repeats[k] = 1;
      continue;
    }
    if (last_informative >= 0)
    {
      const float change =
          last_informative == k - 1 ? stats.change[k] :
                                      meanAbsoluteDifference(map_->keyframe(last_informative), map_->keyframe(k),
                                                             map_->width(), map_->height(), sky);
      stats.repeats[k] = change < stats.stationary_change ? 1 : 0;
    }
    last_informative = k;
  }
  stats.run.assign(n, 0);
  for (int k = 1; k < n; ++k)
    stats.run[k] = stats.run[k - 1] + (stats.repeats[k] ? 0 : 1);
  stats.run_first.assign(n, 0);
  stats.run_last.assign(n, n - 1);
  for (int k = 1; k < n; ++k)
    stats.run_first[k] = stats.run[k] == stats.run[k - 1] ? stats.run_first[k - 1] : k;
  for (int k = n - 2; k >= 0; --k)
    stats.run_last[k] = stats.run[k] == stats.run[k + 1] ? stats.run_last[k + 1] : k;
}

int firstComparedRow(const PreprocessingParams& images)
{
  return std::min(images.skyRows(), images.output_height - 1);  // at least one row below the sky
}

int Localizer::firstComparedRow() const
{
  return along_route_localization::firstComparedRow(map_->params());
}

void Localizer::rebuildComparators()
{
  const int w = map_->width(), h = map_->height();
  const int first_row = firstComparedRow();
  difference_.reset(
      new ImageDifference(w, h, first_row, params_.max_shift_px, params_.subpixel_shift, params_.shift_bands,
                          params_.max_vertical_shift_px));
  homing_.reset(new HomingEstimator(w, h, first_row,
                                    clampedHomingParams(w, h, first_row, params_.homing_max_shift_px,
                                                        params_.homing_max_vertical_shift_px)));
  census_difference_.reset();
  keyframe_census_.clear();
  if (params_.cost_function == CostFunction::kCensus)
  {
    census_difference_.reset(new CensusDifference(w, h, first_row, params_.max_shift_px, params_.subpixel_shift));
    keyframe_census_.resize(map_->size() * map_->keyframeBytes());
    for (size_t k = 0; k < map_->size(); ++k)
      censusTransform(map_->keyframe(k), w, h, keyframe_census_.data() + k * map_->keyframeBytes());
    query_census_.resize(map_->keyframeBytes());
  }
  coarse_difference_.reset();
  coarse_keyframes_.clear();
  const int coarse_shift = (params_.max_shift_px + 1) / 2;
  if (params_.cost_function == CostFunction::kSad && params_.coarse_search_keyframes > 0 &&
      static_cast<int>(map_->size()) >= params_.coarse_search_keyframes && w / 2 > 2 * coarse_shift &&
      first_row / 2 < h / 2)
  {
    // Integer shifts: a coarse row's shifts are not reported (process() measures the answer's at full size).
    coarse_difference_.reset(new ImageDifference(w / 2, h / 2, first_row / 2, coarse_shift, false,
                                                 std::min(params_.shift_bands, h / 2 - first_row / 2)));
    const size_t coarse_bytes = static_cast<size_t>(w / 2) * (h / 2);
    coarse_keyframes_.resize(map_->size() * coarse_bytes);
    halveImages(map_->keyframe(0), map_->size(), w, h, coarse_keyframes_.data());
    coarse_query_.resize(coarse_bytes);
  }
}

void Localizer::reset()
{
  reset(true);
}

void Localizer::reset(bool from_start_keyframe)
{
  ring_.clear();  // (state_ and last_match_: start())
  confirmation_.clear();
  loss_.clear();
  frames_ = 0;
  last_path_.clear();
  entered_query_.release();
  run_position_ = -1.0;
  reckon_position_ = -1.0;
  tracked_frames_ = 0;
  cruise_ = confirmed_cruise_ = CruiseSpeed();
  recent_count_ = recent_next_ = 0;
  clock_.forgetLastStamp();
  start(from_start_keyframe);
}

int Localizer::keyframeThroughRun(int dtw_keyframe)
{
  const int first = map_stats_.run_first[dtw_keyframe], last = map_stats_.run_last[dtw_keyframe];
  if (last == first)
  {
    run_position_ = -1.0;
    return dtw_keyframe;
  }
  const int current = run_position_ < 0.0 ? -1 : static_cast<int>(std::lround(run_position_));
  if (current >= 0 && map_stats_.run_first[current] == first)
  {
    run_position_ = std::min(static_cast<double>(last), run_position_ + run_velocity_);
    return static_cast<int>(std::lround(run_position_));
  }
  // Entering the run: the path's speed before this frame (the robot most likely keeps it: a train stands
  // at a station as long as the teach train did), from the keyframe after the last answer when that came
  // from before the run. Back into the run from after it (the answer had left the station while the robot
  // still stood in it): its last keyframe, the nearest to the last answer; the DTW's own pick among the
  // copies is arbitrary, and was the farthest back the match window allowed
  // (Localizer.StaysAtTheEndOfAStationWhileTheRobotStillStandsThere).
  run_velocity_ = trackSpeed();
  if (last_match_ >= 0 && last_match_ < first)
    run_position_ = std::min(static_cast<double>(last), std::max<double>(first, last_match_ + run_velocity_));
  else
    run_position_ = last_match_ > last ? last : dtw_keyframe;
  return static_cast<int>(std::lround(run_position_));
}

double Localizer::trackSpeed() const
{
  return std::min(static_cast<double>(params_.dtw.max_step), std::max(0.0, pathSpeed(last_path_)));
}

EndPrior Localizer::motionPrior(bool repeated_query) const
{
  EndPrior prior;
  // A new view: the prediction rests on the path's speed, which is the track's own only once the window
  // holds nothing older than the track (a track confirmed a few keyframes behind the robot would
  // otherwise be held there: Localizer.LeavesTheRouteThenRelocalizes, 31 -> 44 frames to be right again).
  if (!repeated_query && tracked_frames_ < params_.ring_buffer_rows)
    return prior;
  prior.weight = params_.motion_prior_weight;
  const bool stood_still = repeated_query && !inRunOfCopies(last_match_);
  prior.center = last_match_ + (stood_still ? 0.0 : trackSpeed());
  prior.cap = repeated_query ? std::numeric_limits<float>::infinity() : params_.motion_prior_cap;
  prior.ahead_only = stood_still;
  return prior;
}

void Localizer::computeRow(const uint8_t* query, float query_energy, bool query_informative, bool repeated_query,
                           bool global, int first, int width, CostRingBuffer* target)
{
  float* costs = raw_costs_.data() + first;
  float* shifts = shifts_.data() + first;
  if (!query_informative)
  {
    // A featureless query's row is neutral whatever the keyframes (below): nothing to compare, and no
    // shift to report.
    std::fill(costs, costs + width, 0.0f);
    std::fill(shifts, shifts + width, 0.0f);
  }
  else if (census_difference_)
  {
    censusTransform(query, map_->width(), map_->height(), query_census_.data());
    const size_t bytes = map_->keyframeBytes();
    const auto run = [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k)
      {
        const ShiftedDifference d =
            census_difference_->compare(query_census_.data(), keyframe_census_.data() + (first + k) * bytes);
        costs[k] = d.cost;
        shifts[k] = d.shift_px;
      }
    };
    if (params_.parallel && width >= 512)
      cv::parallel_for_(cv::Range(0, width), run, std::max(1.0, width / 256.0));
    else
      run(cv::Range(0, width));
  }
  else if (coarse_difference_ && global)
  {
    // Global search on a big map: halved images (coarse_search_keyframes).
    halveImage(query, map_->width(), map_->height(), coarse_query_.data());
    coarse_difference_->compareMany(coarse_query_.data(), coarse_keyframes_.data(), width, costs, shifts,
                                    params_.parallel);
  }
  else
  {
    difference_->compareMany(query, map_->keyframe(first), width, costs, shifts, params_.parallel);
  }
  if (params_.energy_normalized_cost)
  {
    // Two unrelated textured images differ by about 1.4x their energy, a featureless one by exactly
    // the other's energy: dividing by the sum ranks flat regions as unrelated instead of similar.
    for (int k = 0; k < width; ++k)
      costs[k] /= query_energy + map_->energy(first + k) + 1.0f;
  }
  // A featureless query or keyframe says nothing about where we are: it gets the neutral cost 0 (eq. 2
  // output is zero-mean), so dark stretches neither attract nor repel the path.
  for (int k = 0; k < width; ++k)
    mask_[k] = query_informative && map_stats_.informative[first + k];
  float* row = (target ? *target : ring_).appendRow(first, width, repeated_query);
  const float peak = enhanceContrastRuns(
      costs, mask_.data(), map_stats_.stationary_change > 0.0f ? map_stats_.repeats.data() + first : nullptr, width,
      params_.contrast_window, kContrastMinStd, params_.contrast_clamp, 0.0f, row, &contrast_scratch_);
  // Step 3a, an extension: a row whose best match stands out counts more (rowWeight). Only a tracking
  // row, whose peak is over the band (2 * search_radius + 1 keyframes): over the whole map the largest of
  // many scores stands out by chance, so a global search row weighs 1.
  if (!global && query_informative)
  {
    const float weight = rowWeight(peak, params_.row_weight_reference, params_.row_weight_range);
    for (int k = 0; k < width; ++k)
      row[k] *= weight;
  }
}

void StandstillDetector::velocity(double linear_mps, double stamp_s)
{
  if (!std::isfinite(linear_mps) || !std::isfinite(stamp_s))
    return;
  const bool moving = std::fabs(linear_mps) > kStillSpeedMps;
  if (have_sample_ && stamp_s < latest_s_)
    moved_since_frame_ = false;  // time went back: the samples before are of another drive
  moved_since_frame_ = moved_since_frame_ || moving;
  latest_speed_mps_ = linear_mps;
  latest_s_ = stamp_s;
  have_sample_ = true;
}

RobotMotion StandstillDetector::sinceLastFrame(double frame_s)
{
  const bool moved = moved_since_frame_ || std::fabs(latest_speed_mps_) > kStillSpeedMps;
  moved_since_frame_ = false;
  if (!have_sample_ || !std::isfinite(frame_s) || frame_s - latest_s_ > max_age_s_)
    return RobotMotion::kUnknown;
  if (latest_s_ - frame_s > max_age_s_)
  {
    have_sample_ = false;  // samples from the future: time went back (a looping bag)
    latest_speed_mps_ = 0.0;
    return RobotMotion::kUnknown;
  }
  return moved ? RobotMotion::kMoved : RobotMotion::kStoodStill;
}

LocalizationResult Localizer::process(const cv::Mat& preprocessed, int64_t stamp_ns, RobotMotion motion)
{
  if (preprocessed.type() != CV_8UC1 || preprocessed.cols != map_->width() || preprocessed.rows != map_->height())
    throw std::invalid_argument("Localizer: expected a preprocessed mono8 image of " + std::to_string(map_->width()) +
                                "x" + std::to_string(map_->height()) + " (the map's size), got " +
                                cv::typeToString(preprocessed.type()) + " " + std::to_string(preprocessed.cols) +
                                "x" + std::to_string(preprocessed.rows));
  const uint8_t* query = preprocessed.data;
  if (!preprocessed.isContinuous())
  {
    preprocessed.copyTo(query_copy_);
    query = query_copy_.data;
  }
  const FrameClock::Tick tick = clock_.update(stamp_ns);
  if (tick.went_back)
  {
    reset();
    clock_.update(stamp_ns);  // reset() forgot the last stamp: this one is it
  }
  // A featureless frame taken where the last one was (the robot's odometry says it stood still) tells
  // nothing and nothing moved: the sequence, the checks and the dead reckoning stay as they are, and the
  // answer is the last one (after a gap or a restart the frame goes through as any other).
  const float energy = textureEnergy(query, map_->width(), map_->height(), map_->params().skyRows());
  if (motion == RobotMotion::kStoodStill && !tick.went_back && tick.missed == 0 && frames_ > 0 && !textured(energy))
  {
    ++frames_;
    LocalizationResult result = last_result_;
    result.query_informative = false;
    result.shift_px = result.homing_angle_rad = 0.0;  // a featureless query reports no shift
    result.time_went_back = false;
    result.missed_frames = 0;
    result.gap = FrameGap::kNone;
    return result;
  }
  // A frame after a gap that shows the view of the last frame before it, with texture enough to tell: the
  // robot stood still through the gap (a dark view says nothing: the gap is filled in). Not inside a run of
  // identical keyframes (a station where the teach robot stood too): there the robot goes on through the
  // run at the speed it came, as frame by frame (motionPrior, keyframeThroughRun).
  const bool in_run = last_match_ >= 0 && inRunOfCopies(last_match_);
  const bool same_view = tick.missed > 0 && !in_run && repeatsLastView(query) && textured(energy);
  // (FrameClock reports no missed frames when time went back.)
  FrameGap gap = FrameGap::kNone;
  if (tick.missed > 0)
  {
    gap = !params_.fill_frame_gaps ? FrameGap::kNotFilledIn :
          same_view                ? FrameGap::kStoodStill :
          gapRestartsTheSearch(tick.missed) ? FrameGap::kSearchedAgain : FrameGap::kFilledIn;
    if (gap == FrameGap::kFilledIn || gap == FrameGap::kSearchedAgain)
      skipFrames(tick.missed);
  }
  ++frames_;
  LocalizationResult result = step(query, energy);
  result.time_went_back = tick.went_back;
  result.missed_frames = tick.missed;
  result.gap = gap;
  last_result_ = result;
  return result;
}

bool Localizer::repeatsLastView(const uint8_t* query) const
{
  return query && map_stats_.stationary_change > 0.0f && !entered_query_.empty() &&
         meanAbsoluteDifference(query, entered_query_.data, map_->width(), map_->height(), firstComparedRow()) <
             map_stats_.stationary_change;
}

int Localizer::windowRows() const
{
  return params_.method == SequenceMethod::kSeqSlam ? params_.seqslam.sequence_length : params_.ring_buffer_rows;
}

void Localizer::skipFrames(int count)
{
  if (count <= 0)
    return;
  if (gapRestartsTheSearch(count))
  {
    // The frame after the gap would find no row from before it in the window: nothing joins the two
    // sides, and the robot may be anywhere it could drive in that time. A track is lost (the baseline,
    // which has no such status, initializes again); either way the search starts over from an empty
    // window (the recent frames are from before the gap too).
    if (params_.method == SequenceMethod::kSeqSlam)
      transition(State::kInitializing);
    else if (state_ == State::kTracking || state_ == State::kCoasting)
      loseTrack(reckonedAhead(last_match_, count));
    else if (state_ == State::kLost && lost_position_ >= 0.0)  // already lost: its dead reckoning goes on
      lost_position_ = reckonedAhead(lost_position_, count);
    ring_.clear();
    start_.checking = false;
    confirmation_.clear();
    loss_.clear();
    last_path_.clear();
    run_position_ = reckon_position_ = -1.0;
    recent_count_ = recent_next_ = 0;
    lost_frame_ -= count;  // lost (now or before): the robot may have driven on through the missed frames
    posterior_.reset(static_cast<int>(map_->size()), -1);  // anywhere it could drive: the whole route
    return;
  }
  // Each missed frame is a row without evidence, as a featureless frame is: the DTW paths go on through
  // it at any speed it allows (the tie-break keeps the cruise speed), and the frames after the gap tell
  // where the robot went. The results are not reported.
  lost_frame_ -= count;  // lost: the robot may have driven on through the missed frames
  for (int i = 0; i < count; ++i)
    step(nullptr, 0.0f);
}

LocalizationResult Localizer::step(const uint8_t* query, float energy)
{
  Frame frame = beginFrame(query, energy);
  appendRow(frame);
  if (!query && frame.global)
  {
    // A missed frame during a global search: its row is in the window, but matching it over the whole map
    // would cost a global search and say nothing new. It counts as a featureless frame for the
    // confirmation (the robot may have moved on meanwhile).
    confirmation_.update(-1, false, false);
    last_path_.clear();
    if (state_ == State::kLost && lost_position_ >= 0.0)  // the dead reckoning goes on through it
      lost_position_ = reckonedAhead(lost_position_);
    updatePosterior();
    LocalizationResult result;
    result.query_informative = false;
    return result;
  }
  SequenceMatch match = matchSequence(frame);
  if (frame.checking_start && params_.detect_kidnapping)
    checkStart(&frame, &match);

  // Confidence: how much cheaper per row the best path is than the best path ending elsewhere. The
  // reported confidence is about the keyframe (a copy of the same view nearby competes) and weighs that
  // margin by the share of the K rows the path has seen, counting distinct views only (a row of a
  // repeated query, the camera standing still, adds none): after a start or a loss, a margin over 5 rows
  // is a sixth of the evidence of a full window (with 16 000 route-like distractors in the map a wrong
  // stretch confirmed at start-up otherwise looked as sure as a long track). Status decisions go by the
  // confidence in the place (only other runs of keyframes compete), so a station where the map holds
  // many copies of one view does not look like being lost. A global hypothesis is confirmed on that
  // confidence weighed by the same evidence: after a few rows, or on copies of one view (a camera
  // standing still), it must show a bigger margin or wait for more views (unweighted, 2:1 spacing
  // confirmed a wrong place from 5 copies of its first view, and off the route a look-alike was
  // confirmed: Localizer.LeavesTheRouteThenRelocalizes). The loss detection goes by the unweighted
  // confidence: a long track is not lost because the camera stands still.
  const double evidence = evidenceShare(match);
  const double confidence = calibratedConfidence(matchConfidence(match, false, evidence),
                                                 params_.calibration_offset, params_.calibration_slope);
  const bool confident = matchConfidence(match, true, 1.0) >= params_.confidence_threshold;
  const bool confirmable = matchConfidence(match, true, evidence) >= params_.confidence_threshold;

  // The state machine (doc/design.md, section 2): one handler per state the frame came in.
  if (params_.method == SequenceMethod::kSeqSlam)
  {
    if (state_ == State::kInitializing && ring_.size() >= params_.min_init_frames)
      transition(State::kTracking);  // the baseline has no notion of being lost
  }
  else if (!frame.tracking)
    searchStep(frame, match, confirmable);
  else
    trackStep(&frame, &match, confident);
  if (state_ == State::kTracking || state_ == State::kCoasting)
    followTrack(frame, match.keyframe);
  if (frame.borne_out)
    confirmed_cruise_ = cruise_;
  updatePosterior();
  // The frame that moved the track to a confirmed place: that place's confidence, from the check that
  // confirmed it, not the old track's.
  return publish(frame, match.keyframe,
                 frame.moved_by_check ? calibratedConfidence(contradicting_confidence_, params_.calibration_offset,
                                                        params_.calibration_slope) :
                                   confidence);
}

Localizer::Frame Localizer::beginFrame(const uint8_t* query, float energy)
{
  const int n = static_cast<int>(map_->size());
  Frame frame;
  frame.query = query;
  posterior_row_.has_evidence = posterior_row_.newest_is_this_frame = false;
  posterior_row_.width = 0;
  frame.energy = query ? energy : 0.0f;
  frame.informative = query && textured(frame.energy);
  // The query repeats the previous row's view (the camera stood still): flagged for column centering.
  frame.repeated = repeatsLastView(query);
  frame.tracking = last_match_ >= 0 && (state_ == State::kTracking || state_ == State::kCoasting);
  frame.global = params_.method == SequenceMethod::kSeqSlam || !frame.tracking;
  // A known start (start_keyframe) is checked until K new views have come since it: the rows cover the
  // whole map, so that a global search over them can refute the start (startRefuted) when the robot was
  // not there, as soon as a global search would have found the place with the start unknown (a robot
  // standing still elsewhere is not confirmed there before it moves on, ConfirmsAPlaceOnDistinctViews...).
  // While the start's own frame is in the window, every path of the track starts at it.
  frame.checking_start = frame.tracking && params_.method == SequenceMethod::kOnlineDtw && start_.checking &&
                         start_.views < params_.ring_buffer_rows;
  frame.first_from_start = start_.checking && start_.rows == 0;  // no frame answered since the start
  if (start_.checking && !frame.checking_start)
  {
    start_.checking = false;  // enough views to go on its own
    confirmation_.clear();
  }
  // while tracking: one keyframe per frame (the first frame of a known start: the start keyframe)
  frame.predicted = frame.first_from_start ? last_match_ : std::min(n - 1, last_match_ + 1);
  frame.first = 0;
  frame.width = n;
  if (!frame.global)
  {
    // The robot moves forward at most max_step keyframes a frame; centre the band one step ahead.
    frame.first = std::max(0, frame.predicted - params_.search_radius);
    frame.width = std::min(n, frame.predicted + params_.search_radius + 1) - frame.first;
  }
  frame.reach_first = frame.first;
  frame.reach_width = frame.width;
  if (state_ == State::kLost && !params_.detect_kidnapping && params_.method == SequenceMethod::kOnlineDtw &&
      lost_anchor_ >= 0.0)
  {
    // After a loss the robot is where it could have driven since (the rows still cover the whole map; only
    // the match ends there, and only paths there compete): a look-alike far along the route was confirmed
    // and driven to (issue 31, the lens covered for 10 s, seed 3).
    reachableEnds(lost_anchor_, static_cast<int64_t>(frames_) - lost_frame_, &frame.reach_first, &frame.reach_width);
  }
  return frame;
}

void Localizer::reachableEnds(double anchor, int64_t frames, int* first, int* width, int slack) const
{
  // From `slack` (search_radius unless given) keyframes behind where the images last placed the robot (the
  // track may have run ahead of it) to max_step keyframes a frame, and `slack`, ahead of it.
  if (slack < 0)
    slack = params_.search_radius;
  const int n = static_cast<int>(map_->size());
  const int64_t at = std::llround(anchor);
  const int64_t last = std::min<int64_t>(n - 1, at + slack + params_.dtw.max_step * frames);
  *first = static_cast<int>(std::max<int64_t>(0, std::min<int64_t>(last, at - slack)));
  *width = static_cast<int>(last) - *first + 1;
}

void Localizer::appendRow(const Frame& frame)
{
  const int n = static_cast<int>(map_->size());
  const uint8_t* query = frame.query;
  if (state_ == State::kLost && ring_.size() == 0)
  {
    // The first global search after a loss (which cleared the window): the frames before this one, over
    // the whole map. (At most K - 1 of them: the window holds K rows with this frame's.)
    replayRecentQueries(std::min(recent_count_, params_.ring_buffer_rows - 1), &ring_);
  }
  const int first = frame.checking_start ? 0 : frame.first, width = frame.checking_start ? n : frame.width;
  computeRow(query, frame.energy, frame.informative, frame.repeated, frame.checking_start || frame.global, first,
             width);
  if (frame.checking_start)
  {
    ++start_.rows;
    start_.views += query && frame.informative && !frame.repeated ? 1 : 0;
  }
  // This frame's costs (energy-normalized) over the keyframes it was compared with, for step 5's posterior
  // (updatePosterior); a featureless or missed frame brings no evidence, and the posterior's window follows
  // the band all the same. A copy of the last view (the camera standing still) is weighed again: leaving it
  // out lowered fog's worst fold, holding the belief still on it every figure (doc/evaluation_history.md,
  // twenty-eighth round).
  posterior_row_.has_evidence = query && frame.informative;
  posterior_row_.first = first;
  posterior_row_.width = width;
  if (posterior_row_.has_evidence)
    posterior_row_.keep(raw_costs_.data() + first, mask_.data(), first, width);
  if (!recent_queries_.empty())
  {
    RecentQuery& recent = recent_queries_[recent_next_];
    if (query)  // a missed frame's row is featureless: its image is never read
      std::copy(query, query + map_->keyframeBytes(), recent.image.begin());
    recent.energy = frame.energy;
    recent.informative = frame.informative;
    recent.repeated = frame.repeated;
    recent_next_ = (recent_next_ + 1) % static_cast<int>(recent_queries_.size());
    recent_count_ = std::min(recent_count_ + 1, static_cast<int>(recent_queries_.size()));
    posterior_row_.newest_is_this_frame = true;
  }
  if (query)
    cv::Mat(map_->height(), map_->width(), CV_8UC1, const_cast<uint8_t*>(query)).copyTo(entered_query_);
}

SequenceMatch Localizer::matchSequence(const Frame& frame)
{
  const int n = static_cast<int>(map_->size());
  SequenceMatch match;
  if (params_.method == SequenceMethod::kSeqSlam)
    match = seqSlamMatch(ring_, 0, n, params_.seqslam);
  else
  {
    // While tracking, the new match continues from the last one (max_jump_ahead): a step back within the
    // exclusion radius corrects the answer at the same place (e.g. after running on past a stop); a
    // cheaper path further back or far ahead is another place, which still counts against the confidence,
    // so the loss detection and the global search take over if it persists.
    // (The range always holds `predicted`, last_match_ + 1 at most.)
    int first_choice = 0, last_choice = n - 1;
    EndPrior prior;
    if (!frame.global)
    {
      // The robot is between the last place the images confirmed and where the track went since: through
      // frames without evidence (dark, copies of one view, fog) the answer moved on at a speed the images
      // could not check, and may have run ahead of a robot that slowed down. So the new match may also end
      // back at the last confident answer (a known start under check: the start keyframe).
      const int confirmed = last_confident_ >= 0 ? last_confident_ : (start_.checking ? start_.keyframe : last_match_);
      first_choice = std::min(last_match_, confirmed) - params_.dtw.exclusion_radius;
      last_choice = last_match_ + params_.dtw.max_step + params_.max_jump_ahead;
      prior = motionPrior(frame.repeated);
    }
    if (params_.cruise_speed_frames > 0)
      dtw_.setParams(cruiseSpeedTieBreak(params_.dtw, cruise_.speed));
    // The path is backtracked while tracking only (keyframeThroughRun needs its speed): on a global search
    // it would store rows x N step bytes per state for a path that is only drawn in the debug image.
    // A known start while its frame is in the window (the oldest row: the ring was empty at the start):
    // every path starts there.
    const bool start_in_window = start_.rows <= std::min(params_.ring_buffer_rows, ring_.size());
    const int path_start = frame.checking_start && start_in_window ? start_.keyframe : -1;
    match = dtw_.match(ring_, frame.reach_first, frame.reach_width, params_.ring_buffer_rows, !frame.global,
                       map_stats_.run.data(), first_choice, last_choice, prior, path_start);
  }
  last_path_ = match.path;
  // A window without evidence (featureless rows only: a blinded camera, a tunnel longer than K frames)
  // ties every end keyframe: dead-reckon from the last answer at the robot's own speed (its cruise speed,
  // fractional positions carried from frame to frame) instead of taking the first of the ties.
  reckon_position_ = frame.global ? -1.0 : reckonedPosition(frame.first_from_start);
  const int reckoned = static_cast<int>(std::lround(reckon_position_));
  if (frame.global || reckoned < frame.first || reckoned >= frame.first + frame.width ||
      dtw_.lastAccumulated()[reckoned - frame.first] > match.cost)
    reckon_position_ = -1.0;  // the evidence chose: the DTW's answer
  else
    match.keyframe = reckoned;
  if (!frame.global && params_.method == SequenceMethod::kOnlineDtw && params_.run_dead_reckoning)
    match.keyframe = keyframeThroughRun(match.keyframe);
  else
    run_position_ = -1.0;
  return match;
}

void Localizer::checkStart(Frame* frame, SequenceMatch* match)
{
  if (!frame->query)
  {
    confirmation_.update(-1, false, false);  // a missed frame: as in a global search (no search for it)
    return;
  }
  // The images can confirm the start as well as refute it. While they confirm the track by the standard a
  // global search confirms a place by (its place confidence weighed by the distinct views it has seen) and
  // its newest frames alone support its end (as in recentCheck), no place elsewhere refutes it. A robot
  // beside its start, turning onto the route, fits no place in its first frames, and a look-alike could win
  // the global search over them after the robot was back on its route, the track's answers confident
  // (issue 31, closed loop, seed 2 from +1 m +10 deg: refuted on the 27th frame, answers at 0.98 before).
  if (matchConfidence(*match, true, evidenceShare(*match)) >= params_.confidence_threshold &&
      newestRowsSupport(*frame, match->keyframe))
  {
    confirmation_.clear();
    return;
  }
  SequenceMatch elsewhere;
  if (!startRefuted(*match, frame->informative, &elsewhere))
    return;
  // The global search confirmed another place than the known start's track: the track goes on from there.
  *match = elsewhere;
  transition(State::kTracking, elsewhere.keyframe);
  frame->relocated = true;
}

void Localizer::searchStep(const Frame& frame, const SequenceMatch& match, bool confirmable)
{
  // Initializing or lost: a place is confirmed by init_confirm_frames confirmable answers in a row that
  // move as the robot can (GlobalConfirmation), from the min_init_frames-th row on.
  if (ring_.size() >= params_.min_init_frames && confirmation_.update(match.keyframe, confirmable, frame.informative))
    transition(State::kTracking, match.keyframe);
}

void Localizer::trackStep(Frame* frame, SequenceMatch* match, bool confident)
{
  if (confident && frame->informative)
  {
    if (state_ == State::kCoasting)
      transition(State::kTracking);  // evidence again: the DTW's answer
    last_confident_ = match->keyframe;
    frames_since_confident_ = 0;
    // The speed the images have borne out so far (kept in step(), after this frame's own step); a known
    // start under its check is only assumed (without detect_kidnapping it is a fact).
    frame->borne_out = !(frame->checking_start && params_.detect_kidnapping);
  }
  else
    ++frames_since_confident_;
  bool check_started = false;
  if (loss_.update(confident, frame->informative && !frame->repeated))  // new views only
  {
    // A track that no evidence has established (no confident answer yet, or a known start still under
    // its check: only assumed, dead-reckoned through the first frames) has nothing to coast on: lost. A
    // robot that only moves as it drives (detect_kidnapping false) did start there: its start is a fact.
    const bool start_assumed = frame->checking_start && params_.detect_kidnapping;
    if (!params_.loss_needs_contradiction || last_confident_ < 0 || start_assumed)
      loseTrack(match->keyframe);
    else if (state_ == State::kTracking)
    {
      // Weak evidence so far: the robot moved on at its cruise speed since the last confident answer,
      // and the frames are compared with the whole map from now on (trackContradicted).
      transition(State::kCoasting);
      check_started = true;
    }
    loss_.clear();  // the detection counts afresh
  }
  if (state_ == State::kCoasting)
    coastStep(frame, match, check_started);
  else if (state_ == State::kTracking)
    recentCheck(frame, match);
}

void Localizer::NewestFramesCheck::end()
{
  under_way = contradicted = found_contradiction = false;
  unanswered = pending = own_rows = 0;
  confirmation.clear();
}

void Localizer::recentCheck(Frame* frame, SequenceMatch* match)
{
  NewestFramesCheck& check = newest_check_;
  const int rows = std::min(params_.relocalization_rows, params_.ring_buffer_rows);
  if (rows <= 0 || !params_.detect_kidnapping || params_.method != SequenceMethod::kOnlineDtw || frame->global ||
      frame->checking_start || ring_.size() < rows || recent_count_ < rows)
  {
    check.end();  // off, or the start's own check is on, or too few rows to weigh: the next one starts afresh
    return;
  }
  if (!frame->informative || frame->repeated)
  {
    // No new view to weigh. A check under way takes this frame's row (neutral when featureless) with the
    // next new view's, so that its rows stay those of consecutive frames.
    if (check.under_way)
    {
      ++check.pending;
      frame->contradicted = check.contradicted;  // no new view, no new evidence: the last verdict stands
    }
    return;
  }
  // Do the newest rows alone support the track's end? The whole window may still, for K / 2 frames after
  // the robot was carried elsewhere. Supported, the check ends, unless it has found the track contradicted:
  // the band holds only the track's neighbourhood, where a look-alike can support the track by chance while
  // the whole map still holds the place that beats it (below).
  const bool supported = newestRowsSupport(*frame, match->keyframe);
  if (supported && !(check.under_way && check.found_contradiction))
  {
    check.end();
    return;
  }
  // The check's window starts with the newest `rows` frames and grows by each frame it goes on for, up to K
  // rows, as a global search's does: a place elsewhere shown by a few frames more than the newest `rows` is
  // found by their evidence, weighed by K rows (trackContradicted). Kept at `rows`, a check ended unanswered
  // after `rows` frames where the place came out just short of confident, and the track stayed on the old
  // place until the whole window gave it up (kidnapped from the route's end: 57 frames).
  const int check_window = params_.ring_buffer_rows;
  if (check.unanswered >= check_window)
  {
    // As many checks as the window has rows found no place elsewhere: every row now in it came after the
    // first unsupported one, so weak evidence, not another place. Checked again once the track is supported.
    check.under_way = false;
    return;
  }
  // Contradicted: published lost (at the place that contradicts, confidence 0; publish) until the checks
  // confirm that place and the track moves there.
  // Which of the frames held came after a carry is not known: another place contradicts the track over the
  // check's own frames (the newest `rows` until it has that many, then every frame since its first) or over
  // every frame the check holds (up to K), each against the chance margin of its own length. Weighed over all
  // of them alone, the rows from before the check's first frame, the old place's when the robot was carried
  // just before, held the new place back (1-6 frames a carry; doc/evaluation_history.md, thirty-first round);
  // over its own frames alone, a carry some frames before the check began was found later.
  extendCheck(check.under_way ? 1 + check.pending : 0, check_window, &check.ring);
  check.own_rows = check.under_way ? check.own_rows + 1 + check.pending : 1;
  const int own_rows = std::min(check.ring.size(), std::max(rows, check.own_rows));
  frame->contradicted = trackContradicted(match->keyframe, check.ring, own_rows) ||
                        (check.ring.size() > own_rows &&
                         trackContradicted(match->keyframe, check.ring, check.ring.size()));
  check.found_contradiction = (check.under_way && check.found_contradiction) || frame->contradicted;
  // A check that has found the track contradicted goes on while the band supports the track, until the
  // newest rows alone, compared with the whole map, end at the track too (or the checks confirm the other
  // place, or as many checks as the window has rows found none: above). Ended on the band's support alone, it
  // gave a carried robot back to the old place between two lost runs, and the next check started afresh
  // from the newest rows (kidnapped, fold 4: 5 frames in the gtest AContradictedTrackIsNotRestoredByItsBandAlone).
  if (supported && newestRowsEndAt(check.ring, match->keyframe))
  {
    frame->contradicted = false;
    check.end();
    return;
  }
  check.under_way = true;
  check.contradicted = frame->contradicted;
  check.pending = 0;
  check.unanswered = frame->contradicted ? 0 : check.unanswered + 1;
  moveTrackOnConfirmation(&check.confirmation, true, check.ring, frame, match);
}


void Localizer::Coasting::begin(double from)
{
  position = from;
  pending = 0;
  confirmation.clear();  // (the ring: extendCheck starts it afresh on the first frame, check_started)
}

void Localizer::coastStep(Frame* frame, SequenceMatch* match, bool check_started)
{
  int placed = -1;  // where this frame's check placed the robot (trackContradicted), if it did
  if (frame->query)
  {
    // Each frame may bring the evidence of another place; the track moves there once init_confirm_frames
    // checks in a row were contradicted by places that move along the route like the robot can (a
    // single check's winner is a wrong place now and then).
    // The check's window grows to K rows, as a global search's.
    extendCheck(check_started ? 0 : 1 + coasting_.pending, params_.ring_buffer_rows, &coasting_.ring);
    frame->contradicted =
        trackContradicted(static_cast<int>(std::lround(coasting_.position)), coasting_.ring, coasting_.ring.size());
    coasting_.pending = 0;
    if (moveTrackOnConfirmation(&coasting_.confirmation, frame->informative, coasting_.ring, frame, match))
      return;
    placed = coast_fix_;
  }
  else
  {
    ++coasting_.pending;  // a missed frame: no check, but its (featureless) row joins the next one's window
    coasting_.confirmation.update(-1, false, false);
  }
  // Placed by the check: this frame's answer, and the dead reckoning goes on from there. Else a query that
  // repeats the last view: the camera stood still, and so does the dead reckoning.
  if (placed >= 0)
    coasting_.position = placed;
  else if (!frame->repeated)
  {
    // Dead reckoning had already reached the last keyframe and the robot still moves on, showing new
    // views: it has left the route's end, and no position along the route is left to coast on (a robot
    // carried elsewhere from the end of the route was otherwise held there, kidnapped fold 3).
    const bool past_the_end = coasting_.position >= static_cast<double>(map_->size() - 1) && frame->informative &&
                              coastSpeed() > 0.0;
    coasting_.position = reckonedAhead(coasting_.position);
    if (past_the_end)
    {
      loseTrack(coasting_.position);
      return;
    }
  }
  match->keyframe = static_cast<int>(std::lround(coasting_.position));
  run_position_ = -1.0;
}

void Localizer::followTrack(const Frame& frame, int keyframe)
{
  // The cruise speed: the steps of a track followed from one informative frame to the next (a
  // relocalization's jump is not a step; a featureless frame's answer is dead reckoning). Their mean,
  // with the nominal speed as the first sample, until cruise_speed_frames samples; then a moving
  // average over that many.
  if (frame.tracking && !frame.first_from_start && !frame.relocated && frame.informative &&
      params_.cruise_speed_frames > 0)
  {
    const double step = std::min(std::max(keyframe - last_match_, 0), params_.dtw.max_step);
    cruise_.samples = std::min(cruise_.samples + 1, params_.cruise_speed_frames);
    cruise_.speed += (step - cruise_.speed) / cruise_.samples;
  }
  ++tracked_frames_;
  last_match_ = keyframe;
}

void Localizer::PosteriorRow::keep(const float* row_costs, const uint8_t* row_usable, int row_first, int row_width)
{
  costs.assign(row_costs, row_costs + row_width);
  usable.assign(row_usable, row_usable + row_width);
  first = row_first;
  width = row_width;
}

void Localizer::updatePosterior()
{
  // Step 5's posterior: the motion model, then this frame's evidence over the widest row computed for it (the
  // tracking band, or the whole map: a global search, a known start's check, a check of the newest frames).
  if (!params_.posterior_confidence || params_.method != SequenceMethod::kOnlineDtw)
    return;  // not published: not computed
  posterior_.moveTo(posterior_row_.first, posterior_row_.width);  // first: the motion model runs on the band
  posterior_.predict();
  if (posterior_row_.has_evidence)
    posterior_.observe(posterior_row_.costs.data(), posterior_row_.usable.data(), posterior_row_.first,
                       posterior_row_.width);
}

LocalizationResult Localizer::publish(const Frame& frame, int keyframe, double confidence)
{
  LocalizationResult result;
  result.query_informative = frame.informative;
  result.confidence = confidence;
  // Contradicted (published lost), unless dead_reckon_while_lost: the place that contradicts (while tracking,
  // recentCheck, it beat the track's end by more than contradiction_margin_share of chanceMargin; with share
  // 0, where it beat the track at all, else the track's answer), until the checks confirm it.
  if (frame.contradicted && !params_.dead_reckon_while_lost &&
      (state_ == State::kCoasting || contradiction_beats_chance_))
    result.keyframe = contradicting_place_;
  else
    result.keyframe = keyframe;
  // The confidence a probability (posterior_confidence): the posterior's mass within one keyframe of the answer.
  if (params_.posterior_confidence && params_.method == SequenceMethod::kOnlineDtw)
    result.confidence = calibratedConfidence(posterior_.withinOne(result.keyframe), params_.calibration_offset,
                                             params_.calibration_slope);
  // Lost: confidence 0 until the global search confirms a place (the frame that confirms it answers there);
  // the answer is the global search's guess, or (dead_reckon_while_lost) where the robot went at the
  // cruise speed since the loss.
  if (state_ == State::kLost || frame.contradicted)
  {
    result.confidence = 0.0;  // contradicted, or unconfirmed: no chance worth a number
    if (lost_position_ >= 0.0 && params_.dead_reckon_while_lost)
    {
      // The frame that lost the track answers where the track had it (loseTrack: this frame's place); the
      // frames after it, and the one after a gap that lost it (skipFrames: its last missed frame's), one
      // frame of the cruise speed on.
      if (lost_frame_ != static_cast<int64_t>(frames_))
        lost_position_ = reckonedAhead(lost_position_);
      result.keyframe = static_cast<int>(std::lround(lost_position_));
    }
    else if (frame.contradicted && state_ == State::kTracking && last_confident_ >= 0 &&
             params_.dead_reckon_while_lost)
    {
      // Contradicted while tracking: where the robot went at the cruise speed since the last confident answer.
      result.keyframe = static_cast<int>(std::lround(reckonedAhead(last_confident_, frames_since_confident_)));
    }
  }
  result.status = frame.contradicted ? LocalizationStatus::kLost : status();  // lost: contradicted, not unconfirmed
  if (result.keyframe >= 0)
  {
    result.keyframe_stamp_ns = map_->stampNs(result.keyframe);
    if (result.query_informative)  // the homing estimate (homing.h); a featureless query reports none
      result.shift_px = homing_->estimate(frame.query, map_->keyframe(result.keyframe)).shift_px;
    result.homing_angle_rad = homingAngleFromShift(result.shift_px, map_->width(), params_.horizontal_fov_rad);
  }
  return result;
}

LocalizationStatus Localizer::status() const
{
  switch (state_)
  {
    case State::kInitializing:
      return LocalizationStatus::kInitializing;
    case State::kLost:
      return LocalizationStatus::kLost;
    case State::kTracking:
    case State::kCoasting:
      break;
  }
  return last_match_ >= static_cast<int>(map_->size()) - 1 - params_.end_of_route_keyframes ?
             LocalizationStatus::kEndOfRoute :
             LocalizationStatus::kTracking;
}

void Localizer::transition(State next, int place)
{
  // Every change of state_ but the initial one (start()) comes here; what each state needs on entry:
  state_ = next;
  newest_check_.end();  // recentCheck starts afresh in any new state
  switch (next)
  {
    case State::kInitializing:  // the baseline after a gap (skipFrames, which clears the window)
      break;
    case State::kTracking:
      if (place < 0)
        break;  // coasting ended by a confident frame, or the baseline's first answer: the track goes on
      // A place confirmed (a global search, the start's check, the checks while coasting): a new track,
      // which owes nothing to an old one's answers (its last confident one, its dead reckoning while lost).
      last_match_ = place;
      // The steps of a track the images did not bear out (followed since its last confident answer, or a
      // known start the check refuted) were not the robot's: its speed is what it was at that answer.
      cruise_ = confirmed_cruise_;
      last_confident_ = -1;
      frames_since_confident_ = 0;
      lost_position_ = lost_anchor_ = -1.0;
      last_path_.clear();
      run_position_ = reckon_position_ = -1.0;
      tracked_frames_ = 0;
      start_.checking = false;
      confirmation_.clear();
      loss_.clear();
      break;
    case State::kCoasting:
      // Weak evidence: dead reckoning at the cruise speed from the last confident answer.
      coasting_.begin(reckonedAhead(last_confident_, frames_since_confident_ - 1));
      break;
    case State::kLost:
      ring_.clear();  // the rows of a lost track cover only its band (or a start's check's, its first frames)
      start_.checking = false;
      confirmation_.clear();
      break;
  }
}

double Localizer::reckonedPosition(bool first_from_start) const
{
  if (first_from_start)
    return last_match_;  // the first frame of a known start is at the start keyframe
  const double from = reckon_position_ >= 0.0 ? reckon_position_ : static_cast<double>(last_match_);
  return reckonedAhead(from);
}

double Localizer::reckonedAhead(double position, double frames) const
{
  return std::min(static_cast<double>(map_->size() - 1), position + coastSpeed() * frames);
}

double Localizer::coastSpeed() const
{
  return std::min(static_cast<double>(params_.dtw.max_step), std::max(0.0, cruise_.speed));
}

void Localizer::loseTrack(double track_position)
{
  lost_position_ = lost_anchor_ = track_position;
  lost_frame_ = static_cast<int64_t>(frames_);
  transition(State::kLost);
}

bool Localizer::newestRowsSupport(const Frame& frame, int track_keyframe)
{
  const int rows = std::min(params_.relocalization_rows, params_.ring_buffer_rows);
  if (rows <= 0 || ring_.size() < rows)
    return false;
  const SequenceMatch newest = dtw_.match(ring_, frame.first, frame.width, rows, false, map_stats_.run.data(),
                                          track_keyframe, track_keyframe);
  return matchConfidence(newest, true, 1.0) >= params_.confidence_threshold;
}

bool Localizer::newestRowsEndAt(const CostRingBuffer& check, int place)
{
  const int rows = std::min({ params_.relocalization_rows, params_.ring_buffer_rows, check.size() });
  if (rows <= 0 || place < 0)
    return false;
  const SequenceMatch newest =
      dtw_.match(check, 0, static_cast<int>(map_->size()), rows, false, map_stats_.run.data());
  return newest.keyframe >= 0 && samePlace(newest.keyframe, place);
}

bool Localizer::samePlace(int a, int b) const
{
  return std::abs(map_stats_.run[a] - map_stats_.run[b]) <= params_.dtw.exclusion_radius;
}

void Localizer::extendCheck(int new_rows, int window, CostRingBuffer* ring)
{
  const int n = static_cast<int>(map_->size());
  if (recent_count_ < 1)
    return;  // nothing to weigh
  if (new_rows > 0 && new_rows < window && new_rows <= recent_count_ && ring->size() > 0 &&
      ring->capacity() == window && ring->maxWidth() == n)
  {
    replayRecentQueries(new_rows, ring);  // the check goes on: only the frames since its last row are new
  }
  else
  {
    if (ring->capacity() != window || ring->maxWidth() != n)
      ring->resize(window, n);
    ring->clear();
    replayRecentQueries(std::min(recent_count_, window), ring);
  }
}

bool Localizer::trackContradicted(int track_keyframe, const CostRingBuffer& ring, int rows)
{
  const int n = static_cast<int>(map_->size());
  coast_fix_ = -1;
  rows = std::min(rows, ring.size());
  if (recent_count_ < 1 || rows < 1)
    return false;  // nothing to weigh
  // A robot that only moves as it drives (detect_kidnapping false; coasting: the newest rows' check is
  // off) is contradicted only by a place it could have driven to since the last confident answer.
  int first = 0, width = n;
  if (!params_.detect_kidnapping && last_confident_ >= 0)
    reachableEnds(last_confident_, frames_since_confident_, &first, &width);
  // The chance margins run the DTW when first measured: before this check's match, whose costs
  // (dtw_.lastAccumulated) trackEndCost reads below.
  if (state_ == State::kCoasting || params_.contradiction_margin_share > 0.0)
    chanceMargin(rows);
  const SequenceMatch elsewhere = dtw_.match(ring, first, width, rows, false, map_stats_.run.data());
  contradicting_place_ = elsewhere.keyframe;
  contradiction_beats_chance_ = false;
  if (elsewhere.keyframe < 0)
    return false;
  const bool at_track = samePlace(elsewhere.keyframe, track_keyframe);
  if (state_ == State::kCoasting)
  {
    // Evidence placing the robot where it can be is no contradiction: the dead reckoning moves there. The
    // sequence's end next to the reckoned keyframe, or one the robot can have driven to since the last
    // confident answer (forward, at most max_step keyframes a frame, give or take the exclusion radius)
    // that is better than the reckoned end by more than chance (a robot that stood still or sped up while
    // the images said little: dead reckoning at the cruise speed does not know). Asking the end next to the
    // reckoning to stand out as a place too measured a little lower (doc/evaluation_history.md).
    int reach_first = 0, reach_width = 0;
    reachableEnds(last_confident_, frames_since_confident_, &reach_first, &reach_width, params_.dtw.exclusion_radius);
    const bool reachable = elsewhere.keyframe >= reach_first && elsewhere.keyframe < reach_first + reach_width;
    const float margin =
        reachable ? trackEndCost(track_keyframe, params_.dtw.exclusion_radius, first, width) - elsewhere.cost : 0.0f;
    if (at_track || (reachable && margin > chanceMargin(rows)))
    {
      coast_fix_ = elsewhere.keyframe;
      return false;
    }
  }
  if (at_track)
    return false;  // the sequence still ends at the track's place
  // As a global search confirms a place: its confidence weighed by the distinct views among K rows, however
  // few the check's window holds (weighed by its own 8 rows, the check while tracking moved the track to
  // look-alike places of the synthetic routes: seed 4, within one 1.000 -> 0.787).
  const double evidence =
      std::min(1.0, static_cast<double>(ring.distinctViews(elsewhere.rows)) / std::max(1, params_.ring_buffer_rows));
  contradicting_confidence_ = matchConfidence(elsewhere, false, evidence);
  if (matchConfidence(elsewhere, true, evidence) < params_.confidence_threshold)
    return false;  // no place stands out: weak evidence
  const bool against_chance = params_.contradiction_margin_share > 0.0;
  if (!against_chance && state_ != State::kTracking)
    return true;  // coasting: the place that contradicts is published as it is (publish)
  // Better than the track's own end over the same rows by more than contradiction_margin_share of what a
  // wrong stretch of this map beats another by, by chance (chanceMargin, measured above). On a repeat
  // beside the taught line, places that beat a right track by less were look-alikes the checks confirmed
  // (doc/results.md, "A repeat beside the taught line").
  const float margin =
      trackEndCost(track_keyframe, params_.dtw.max_step + params_.max_jump_ahead, first, width) - elsewhere.cost;
  contradiction_beats_chance_ =
      margin > (against_chance ? static_cast<float>(params_.contradiction_margin_share) * chanceMargin(rows) : 0.0f);
  return !against_chance || contradiction_beats_chance_;
}

float Localizer::trackEndCost(int track_keyframe, int ahead, int first, int width) const
{
  const std::vector<float>& accumulated = dtw_.lastAccumulated();  // [k - first]
  const int lo = std::max(first, track_keyframe - params_.dtw.exclusion_radius);
  const int hi = std::min(first + width - 1, track_keyframe + ahead);
  float cost = std::numeric_limits<float>::infinity();
  for (int k = lo; k <= hi; ++k)
    cost = std::min(cost, accumulated[k - first]);
  return cost;
}

void Localizer::replayRecentQueries(int count, CostRingBuffer* target)
{
  const int n = static_cast<int>(map_->size());
  const int capacity = static_cast<int>(recent_queries_.size());
  for (int i = recent_count_ - count; i < recent_count_; ++i)
  {
    const RecentQuery& recent = recent_queries_[(recent_next_ - recent_count_ + i + capacity) % capacity];
    computeRow(recent.image.data(), recent.energy, recent.informative, recent.repeated, true, 0, n, target);
    // This frame over the whole map (a check of the newest frames): the posterior weighs all of it.
    if (i == recent_count_ - 1 && posterior_row_.newest_is_this_frame && posterior_row_.has_evidence &&
        posterior_row_.width < n)
      posterior_row_.keep(raw_costs_.data(), mask_.data(), 0, n);
  }
}

bool Localizer::moveTrackOnConfirmation(GlobalConfirmation* confirmation, bool informative,
                                        const CostRingBuffer& check, Frame* frame, SequenceMatch* match)
{
  if (!confirmation->update(frame->contradicted ? contradicting_place_ : -1, frame->contradicted, informative))
    return false;
  const int keyframe = contradicting_place_;
  match->keyframe = keyframe;
  frame->relocated = frame->moved_by_check = true;
  frame->contradicted = false;
  // The check's whole-map rows become the window (they cover any band); the track starts afresh there.
  ring_.clear();
  const int n = static_cast<int>(map_->size());
  for (int age = check.size() - 1; age >= 0; --age)
  {
    float* row = ring_.appendRow(0, n, check.repeatedQuery(age));
    for (int k = 0; k < n; ++k)
      row[k] = check.at(age, k, 0.0f);
  }
  transition(State::kTracking, keyframe);
  return true;
}

float Localizer::chanceMargin(int rows)
{
  if (map_stats_.chance_margins.empty())
    measureChanceMargins();
  const int most = static_cast<int>(map_stats_.chance_margins.size()) - 1;
  return map_stats_.chance_margins[std::max(0, std::min(rows, most))];
}

void Localizer::measureChanceMargins()
{
  // Stretches of this map's own keyframes are the queries, and their true places are left out: the
  // cheapest path at a wrong place then beats the track-sized stretch of ends at another wrong place by
  // the chance margin of this map. Sampled at kChanceWindows evenly spaced stretches, the largest kept,
  // for every window a check may weigh (relocalization_rows growing to K): the newest r rows of each
  // stretch's `most` rows give the margin over r rows, so each stretch's rows are computed once.
  const int n = static_cast<int>(map_->size());
  // With the DTW's own parameters, whenever it is measured (a track sets the cruise speed's tie-break per
  // frame, matchSequence), and those restored after it.
  const DtwParams tracking_dtw = dtw_.params();
  dtw_.setParams(params_.dtw);
  const int most = std::max(0, std::min(std::max(params_.ring_buffer_rows, params_.relocalization_rows), n - 1));
  std::vector<float>& largest = map_stats_.chance_margins;
  largest.assign(most + 1, 0.0f);
  const int window = params_.dtw.exclusion_radius + params_.dtw.max_step + params_.max_jump_ahead + 1;
  CostRingBuffer ring(std::max(1, most), n);  // once per map and parameters: no need to keep it
  std::vector<int> measured(most + 1, 0);  // [rows]: stretches that left a wrong place to measure on
  for (int sample = 0; sample < kChanceWindows && most > 0; ++sample)
  {
    const int a = static_cast<int>(static_cast<int64_t>(sample) * (n - most) / kChanceWindows);
    ring.clear();
    for (int i = 0; i < most; ++i)
      computeRow(map_->keyframe(a + i), map_->energy(a + i), map_stats_.informative[a + i] != 0, false, true, 0, n,
                 &ring);
    const int last = a + most - 1;  // the stretch's newest keyframe
    const int start = ((a + n / 2) % n);  // a track-sized stretch of ends halfway round the map from this one
    for (int rows = 1; rows <= most; ++rows)
    {
      dtw_.match(ring, 0, n, rows, false, map_stats_.run.data());
      const std::vector<float>& accumulated = dtw_.lastAccumulated();
      // The true place of the newest `rows` keyframes, and what eq. 2 spread of it.
      const int reach = params_.contrast_window + params_.dtw.exclusion_radius + rows * params_.dtw.max_step;
      const int lo = last - rows + 1 - reach, hi = last + reach;
      float best_wrong = std::numeric_limits<float>::infinity();
      for (int k = 0; k < n; ++k)
        if (k < lo || k > hi)
          best_wrong = std::min(best_wrong, accumulated[k]);
      // The track-sized stretch of ends at another wrong place (from `start`).
      float track_wrong = std::numeric_limits<float>::infinity();
      for (int k = start; k < std::min(n, start + window); ++k)
        if (k < lo || k > hi)
          track_wrong = std::min(track_wrong, accumulated[k]);
      if (std::isfinite(best_wrong) && std::isfinite(track_wrong))
      {
        largest[rows] = std::max(largest[rows], track_wrong - best_wrong);
        ++measured[rows];
      }
    }
  }
  // On a short map a long window's true place and what eq. 2 spread of it leave no wrong place for most
  // stretches (149 keyframes, K = 30: from 26 rows on, 7 stretches of 20 or none, margins 0-0.07 against
  // 0.5 at 25 rows), and a margin of 0 would let any place that stands out contradict the track. Measured
  // on fewer than half the stretches, a window takes the margin of the next shorter one.
  for (int rows = 2; rows <= most; ++rows)
    if (measured[rows] < kChanceWindows / 2)
      largest[rows] = largest[rows - 1];
  // Shorter still (under about 50 keyframes with the defaults), not one stretch leaves a wrong place even
  // for one row: chance cannot be measured on this map, and no margin is safe to beat, so none can be
  // beaten (infinity): the checks that weigh against chance (contradiction_margin_share > 0, the coasting
  // check's fix) never move the track or lose it there; the DTW alone answers.
  if (most > 0 && measured[1] == 0)
    std::fill(largest.begin() + 1, largest.end(), std::numeric_limits<float>::infinity());
  dtw_.setParams(tracking_dtw);
}

double Localizer::evidenceShare(const SequenceMatch& match) const
{
  return std::min(1.0, static_cast<double>(ring_.distinctViews(match.rows)) / std::max(1, windowRows()));
}

double Localizer::matchConfidence(const SequenceMatch& match, bool other_place, double evidence) const
{
  const bool has_reference = other_place ? match.has_second_place : match.has_second;
  const float reference_cost = other_place ? match.second_place_cost : match.second_cost;
  const float reference = has_reference ? reference_cost : params_.dtw.missing_cost;
  const double margin = std::max(0.0f, reference - match.cost);
  return 1.0 - std::exp(-margin * evidence / params_.confidence_scale);
}

bool Localizer::startRefuted(const SequenceMatch& track, bool informative, SequenceMatch* elsewhere)
{
  // The global search over the same rows, with no start: as at start-up without a known start, a place
  // is confirmed by init_confirm_frames confirmable answers in a row that move as the robot can, from the
  // min_init_frames-th row on.
  if (ring_.size() < params_.min_init_frames)
    return false;
  *elsewhere = dtw_.match(ring_, 0, static_cast<int>(map_->size()), params_.ring_buffer_rows, false,
                          map_stats_.run.data());
  if (start_.first_answer < 0 && informative)
  {
    start_.first_answer = elsewhere->keyframe;
    start_.first_answer_row = start_.rows;
  }
  const bool confirmable =
      matchConfidence(*elsewhere, true, evidenceShare(*elsewhere)) >= params_.confidence_threshold;
  if (!confirmation_.update(elsewhere->keyframe, confirmable, informative))
    return false;
  confirmation_.clear();
  // Confirmed at the track's place (copies of one view count as one place): the start holds.
  if (samePlace(elsewhere->keyframe, track.keyframe))
    return false;
  // The start is prior knowledge: another place refutes it only when the images showed that place from the
  // check's first answer on (the robot could have driven from there to here). A robot started elsewhere is
  // seen there from its first frames; a robot beside its start, still turning onto the route, fits no place
  // well, and the answers go from one look-alike to another before one is confirmed.
  const int advance = elsewhere->keyframe - start_.first_answer;
  const int frames = start_.rows - start_.first_answer_row;
  return advance >= -params_.dtw.exclusion_radius &&
         advance <= params_.dtw.max_step * frames + params_.dtw.exclusion_radius;
}

cv::Mat Localizer::renderDebugImage(int first_keyframe, int width, int scale) const
{
  DebugImageContent content;
  content.first_keyframe = first_keyframe;
  content.keyframes = std::max(1, width);
  content.path = last_path_;
  content.match_keyframe = last_match_;
  content.status = toString(status());
  content.cost_clamp = params_.contrast_clamp;
  content.cell_px = std::max(1, scale);
  cv::Mat image;
  along_route_localization::renderDebugImage(ring_, content, image);
  return image;
}

}  // namespace along_route_localization
