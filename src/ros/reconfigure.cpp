#include "ros/reconfigure.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <ros/console.h>

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

KeyframePolicy toPolicy(const MapRecorderConfig& config)
{
  KeyframePolicy policy;
  policy.every_nth = config.every_nth;
  policy.min_time_gap_s = config.min_time_gap;
  policy.min_appearance_change = config.min_appearance_change;
  policy.min_distance_m = config.min_distance;
  return policy;
}

namespace
{

std::string text(double value)
{
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

}  // namespace

std::vector<std::string> correctToTable(dynamic_reconfigure::Config* msg, const dynamic_reconfigure::Config& previous)
{
  std::vector<std::string> corrections;
  const auto number = [&](const std::string& name, double given, double before, double* used) {
    const ParameterSpec* spec = findParameter(name);
    if (!spec)
      return;
    const std::string sentence = correctNumber(*spec, given, before, used);
    if (!sentence.empty())
      corrections.push_back(sentence);
  };
  for (dynamic_reconfigure::IntParameter& value : msg->ints)
  {
    const dynamic_reconfigure::IntParameter* before = findByName(previous.ints, value.name);
    double used = value.value;
    number(value.name, value.value, before ? before->value : value.value, &used);
    value.value = static_cast<int>(used);
  }
  for (dynamic_reconfigure::DoubleParameter& value : msg->doubles)
  {
    const dynamic_reconfigure::DoubleParameter* before = findByName(previous.doubles, value.name);
    number(value.name, value.value, before ? before->value : value.value, &value.value);
  }
  for (dynamic_reconfigure::StrParameter& value : msg->strs)
  {
    const ParameterSpec* spec = findParameter(value.name);
    const dynamic_reconfigure::StrParameter* before = findByName(previous.strs, value.name);
    if (!spec || spec->type != ParameterType::kChoice || !before ||
        std::find(spec->choices.begin(), spec->choices.end(), value.value) != spec->choices.end())
      continue;
    corrections.push_back(value.name + " '" + value.value + "' is not one of " + spec->rangeText() + "; keeping " +
                          before->value);
    value.value = before->value;
  }
  return corrections;
}

std::vector<std::string> configChanges(const dynamic_reconfigure::Config& before, const dynamic_reconfigure::Config& after)
{
  std::vector<std::string> changes;
  for (const dynamic_reconfigure::IntParameter& value : after.ints)
    if (const dynamic_reconfigure::IntParameter* old = findByName(before.ints, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + std::to_string(old->value) + " -> " + std::to_string(value.value));
  for (const dynamic_reconfigure::DoubleParameter& value : after.doubles)
    if (const dynamic_reconfigure::DoubleParameter* old = findByName(before.doubles, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + text(old->value) + " -> " + text(value.value));
  for (const dynamic_reconfigure::StrParameter& value : after.strs)
    if (const dynamic_reconfigure::StrParameter* old = findByName(before.strs, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + old->value + " -> " + value.value);
  for (const dynamic_reconfigure::BoolParameter& value : after.bools)
    if (const dynamic_reconfigure::BoolParameter* old = findByName(before.bools, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + (old->value ? "true" : "false") + " -> " + (value.value ? "true" : "false"));
  return changes;
}

void logConfigReview(const ConfigReview& review, const std::string& logger, const std::string& what)
{
  for (const std::string& correction : review.corrections)
    ROS_WARN_NAMED(logger, "%s", correction.c_str());
  if (!review.rejected.empty())
    ROS_ERROR_NAMED(logger, "Rejected %s: %s; keeping the previous ones", what.c_str(), review.rejected.c_str());
  for (const std::string& change : review.changes)
    ROS_INFO_NAMED(logger, "%s", change.c_str());
}

}  // namespace along_route_localization
