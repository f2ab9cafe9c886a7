#include "ros/reconfigure.h"

#include <cmath>

namespace along_route_localization
{

PreprocessingParams toParams(const PreprocessorConfig& config, std::string* problem)
{
  PreprocessingParams params;
  params.output_width = config.output_width;
  params.output_height = config.output_height;
  if (!normalizationFromString(config.normalization, &params.normalization))
  {
    params.normalization = NormalizationMethod::kPatch;
    if (problem)
      *problem = "normalization must be 'divisive', 'patch' or 'none', got '" + config.normalization + "'";
  }
  params.patch_size = config.patch_size;
  params.min_patch_std = config.min_patch_std;
  params.filter_window = config.filter_window;
  params.normalization_strength = config.normalization_strength;
  params.output_gain = config.output_gain;
  params.sky_fraction = config.sky_fraction;
  return params;
}

LocalizerParams toParams(const LocalizerConfig& config, LocalizerParams params, std::string* problem)
{
  if (!sequenceMethodFromString(config.method, &params.method))
  {
    params.method = SequenceMethod::kOnlineDtw;
    if (problem)
      *problem = "method must be 'dtw' or 'seqslam', got '" + config.method + "'";
  }
  params.ring_buffer_rows = config.ring_buffer_rows;
  params.dtw.max_step = config.max_step;
  params.max_shift_px = config.max_shift_px;
  params.contrast_window = config.contrast_window;
  params.search_radius = config.search_radius;
  params.confidence_threshold = config.confidence_threshold;
  params.dtw.stop_penalty = static_cast<float>(config.stop_penalty);
  params.dtw.skip_penalty = static_cast<float>(config.skip_penalty);
  params.motion_prior_weight = static_cast<float>(config.motion_prior_weight);
  params.horizontal_fov_rad = config.horizontal_fov_deg * M_PI / 180.0;
  params.lost_after_frames = config.lost_after_frames;
  params.lost_window_frames = config.lost_window_frames;
  return params;
}

RouteFollowerParams toParams(const RouteFollowerConfig& config)
{
  RouteFollowerParams params;
  params.homing_gain = config.homing_gain;
  params.max_homing_turn_rps = config.max_homing_turn_rate;
  params.homing_time_constant_s = config.homing_time_constant;
  params.speed_factor = config.speed_factor;
  params.min_confidence = config.min_confidence;
  params.slow_after_frames = config.slow_after_frames;
  params.stop_after_frames = config.stop_after_frames;
  params.slow_factor = config.slow_factor;
  params.watchdog_timeout_s = config.watchdog_timeout;
  params.max_linear_accel = config.max_linear_accel;
  params.max_angular_accel = config.max_angular_accel;
  return params;
}

}  // namespace along_route_localization
