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
#include "along_route_localization/image_difference.h"
#include "along_route_localization/online_dtw.h"
#include "along_route_localization/route_map.h"
#include "along_route_localization/seqslam.h"

namespace along_route_localization
{

enum class LocalizationStatus
{
  kInitializing,  ///< collecting frames for the first global sequence search
  kTracking,      ///< following the route within the search band
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

/// Parameters of steps 2-5. Units in the comments; validate() gives the allowed ranges.
struct LocalizerParams
{
  SequenceMethod method = SequenceMethod::kOnlineDtw;
  CostFunction cost_function = CostFunction::kSad;
  int ring_buffer_rows = 30;          ///< K, frames in the sequence window
  int max_shift_px = 4;               ///< m, horizontal shift search range, px of the preprocessed image
  bool subpixel_shift = true;
  int contrast_window = 10;           ///< n, eq. 2 half window, keyframes
  float contrast_min_std = 0.01f;     ///< floor of the eq. 2 std (cost units)
  float contrast_clamp = 2.0f;        ///< |enhanced cost| limit
  /// A frame or keyframe whose textureEnergy is below min_texture_ratio * output_gain is featureless
  /// (normal frames score about 0.8 * output_gain after patch normalization).
  float min_texture_ratio = 0.3f;
  /// Divide each SAD by the sum of the two images' texture energies (step 2b), so that partly
  /// featureless keyframes do not look similar to every query.
  bool energy_normalized_cost = true;
  int search_radius = 40;             ///< keyframes computed on each side of the predicted match while tracking
  DtwParams dtw;                      ///< s (max_step), stop and skip penalties, exclusion radius
  SeqSlamParams seqslam;              ///< baseline only
  int min_init_frames = 5;            ///< frames before the first global answer
  double confidence_threshold = 0.2;  ///< below it a frame counts as low-confidence
  float confidence_scale = 0.5f;      ///< per-row cost margin that maps to confidence 1 - 1/e
  int lost_after_frames = 10;         ///< consecutive low-confidence frames before a global search
  int end_of_route_keyframes = 2;     ///< a match this close to the last keyframe reports kEndOfRoute
  double horizontal_fov_rad = 1.0;    ///< camera horizontal field of view, for the homing angle
  bool parallel = true;               ///< spread global searches over cores

  std::string validate() const;
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
};

/// Homing angle from an image shift: a scene displaced d px to the right means the camera yawed left,
/// so the correction is a right turn: angle = -atan(d / f), with f = (width / 2) / tan(hfov / 2) px.
double homingAngleFromShift(double shift_px, int image_width, double horizontal_fov_rad);

/// The per-frame localizer. Not thread-safe: call from one thread (the nodelet's callback queue).
class Localizer
{
public:
  /// Throws std::invalid_argument for an empty map or invalid params.
  Localizer(std::shared_ptr<const RouteMap> map, const LocalizerParams& params);

  /// Applies new parameters between frames. Buffers are resized; the current match and status are
  /// kept when the sequence settings allow it. Throws std::invalid_argument for invalid params.
  void setParams(const LocalizerParams& params);
  const LocalizerParams& params() const { return params_; }

  /// Processes one preprocessed image (CV_8UC1, the map's size). Throws std::invalid_argument otherwise.
  LocalizationResult process(const cv::Mat& preprocessed);

  /// Forgets the sequence (e.g. time jumped back); the next frames initialize globally.
  void reset();

  const RouteMap& map() const { return *map_; }
  const CostRingBuffer& costs() const { return ring_; }
  /// Best path of the last frame, one keyframe per ring-buffer row, oldest first.
  const std::vector<int>& lastPath() const { return last_path_; }
  /// Frames processed since construction or reset().
  uint64_t frameCount() const { return frames_; }

  /// The paper's figure 4: ring buffer (rows = frames, newest at the bottom; columns = keyframes of
  /// [first, first + width)) as a gray image, dark = low cost, with the current path in red. BGR8.
  cv::Mat renderDebugImage(int first_keyframe, int width, int scale = 4) const;

private:
  void rebuildComparators();
  void computeRow(const uint8_t* query, float query_energy, bool query_informative, int first, int width);

  std::shared_ptr<const RouteMap> map_;
  LocalizerParams params_;
  std::unique_ptr<ImageDifference> difference_;
  std::unique_ptr<CensusDifference> census_difference_;
  std::vector<uint8_t> keyframe_census_;   // census codes of all keyframes, when that cost is used
  std::vector<uint8_t> query_census_;
  std::vector<uint8_t> keyframe_informative_;
  float min_texture_energy_ = 0.0f;        // min_texture_ratio * the map's output_gain
  CostRingBuffer ring_;
  OnlineDtw dtw_;

  // per-frame scratch, sized once per map / parameter change
  std::vector<float> raw_costs_, shifts_;              // indexed by keyframe; valid in the newest band
  std::vector<uint8_t> mask_;                          // informative entries of the newest band
  cv::Mat query_copy_;                                 // only for non-continuous input
  int newest_first_ = 0, newest_width_ = 0;            // band of the newest row

  LocalizationStatus status_ = LocalizationStatus::kInitializing;
  int last_match_ = -1;
  int low_confidence_frames_ = 0;
  uint64_t frames_ = 0;
  std::vector<int> last_path_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_LOCALIZER_H
