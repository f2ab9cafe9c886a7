// The taught route: keyframes as preprocessed bytes, stored contiguously, with their source stamps.
#ifndef ALONG_ROUTE_LOCALIZATION_ROUTE_MAP_H
#define ALONG_ROUTE_LOCALIZATION_ROUTE_MAP_H

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "along_route_localization/preprocessing.h"

namespace along_route_localization
{

class MapError : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// The map recorder's keyframe policy: a frame becomes a keyframe when every enabled criterion holds
/// (0 disables one); with all of them 0 every frame is a keyframe.
struct KeyframePolicy
{
  int every_nth = 1;                   ///< keep every n-th frame (1: every frame)
  double min_time_gap_s = 0.0;         ///< s since the last keyframe, from the header stamps
  double min_appearance_change = 0.0;  ///< mean |byte difference| to the last keyframe, gray levels
  double min_distance_m = 0.0;         ///< m travelled since the last keyframe, from odometry
};

/// Keyframe k occupies bytes [k * w * h, (k + 1) * w * h) of one contiguous buffer, so the image
/// difference streams through the map without indirection. Each keyframe keeps the stamp of the camera
/// frame it came from (nanoseconds since the epoch of that clock) and its texture energy.
class RouteMap
{
public:
  RouteMap() = default;
  explicit RouteMap(const PreprocessingParams& params);

  const PreprocessingParams& params() const { return params_; }
  int width() const { return params_.output_width; }
  int height() const { return params_.output_height; }
  size_t keyframeBytes() const { return static_cast<size_t>(width()) * height(); }

  /// Appends a copy of a preprocessed image (CV_8UC1, height() x width()); throws MapError otherwise.
  void addKeyframe(const cv::Mat& preprocessed, int64_t stamp_ns);
  void reserve(size_t keyframes);

  size_t size() const { return stamps_ns_.size(); }
  bool empty() const { return stamps_ns_.empty(); }
  const uint8_t* keyframe(size_t index) const { return data_.data() + index * keyframeBytes(); }
  const uint8_t* data() const { return data_.data(); }
  /// Non-owning view of keyframe `index`.
  cv::Mat keyframeMat(size_t index) const;
  int64_t stampNs(size_t index) const { return stamps_ns_[index]; }
  /// textureEnergy() of each keyframe (below the sky rows), computed when it was added.
  float energy(size_t index) const { return energy_[index]; }

private:
  PreprocessingParams params_;
  std::vector<uint8_t> data_;
  std::vector<int64_t> stamps_ns_;
  std::vector<float> energy_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROUTE_MAP_H
