#include "along_route_localization/parameters.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>

namespace along_route_localization
{

namespace
{

using Setter = std::function<bool(const std::string&, PreprocessingParams*, LocalizerParams*)>;

bool parseDouble(const std::string& text, double* value)
{
  try
  {
    size_t used = 0;
    *value = std::stod(text, &used);
    return used == text.size();
  }
  catch (const std::exception&)
  {
    return false;
  }
}

bool parseInt(const std::string& text, int* value)
{
  double d;
  if (!parseDouble(text, &d) || d != std::floor(d) || std::abs(d) > 2e9)
    return false;
  *value = static_cast<int>(d);
  return true;
}

bool parseBool(const std::string& text, bool* value)
{
  // The forms YAML 1.1 (rosparam, roslaunch) reads as booleans, and 1 / 0.
  static const std::set<std::string> yes = { "true", "True", "TRUE", "yes", "Yes", "YES", "on", "On", "ON", "1" };
  static const std::set<std::string> no = { "false", "False", "FALSE", "no", "No", "NO", "off", "Off", "OFF", "0" };
  if (yes.count(text))
    *value = true;
  else if (no.count(text))
    *value = false;
  else
    return false;
  return true;
}

template <typename T>
Setter number(T PreprocessingParams::*field)
{
  return [field](const std::string& v, PreprocessingParams* p, LocalizerParams*) {
    double d;
    int i;
    if (std::is_integral<T>::value)
      return parseInt(v, &i) && ((p->*field = static_cast<T>(i)), true);
    return parseDouble(v, &d) && ((p->*field = static_cast<T>(d)), true);
  };
}

template <typename T, typename Getter>
Setter localizerNumber(Getter get)
{
  return [get](const std::string& v, PreprocessingParams*, LocalizerParams* l) {
    double d;
    int i;
    if (std::is_integral<T>::value)
      return parseInt(v, &i) && ((get(l) = static_cast<T>(i)), true);
    return parseDouble(v, &d) && ((get(l) = static_cast<T>(d)), true);
  };
}

#define LOCALIZER_FIELD(type, expr) localizerNumber<type>([](LocalizerParams* l) -> type& { return l->expr; })

// Preprocessing (step 1): the preprocessor's parameters, stored in the map.
const std::map<std::string, Setter>& preprocessingSetters()
{
  static const std::map<std::string, Setter> table = {
    { "output_width", number(&PreprocessingParams::output_width) },
    { "output_height", number(&PreprocessingParams::output_height) },
    { "normalization",
      [](const std::string& v, PreprocessingParams* p, LocalizerParams*) { return normalizationFromString(v, &p->normalization); } },
    { "patch_size", number(&PreprocessingParams::patch_size) },
    { "min_patch_std", number(&PreprocessingParams::min_patch_std) },
    { "filter_window", number(&PreprocessingParams::filter_window) },
    { "normalization_strength", number(&PreprocessingParams::normalization_strength) },
    { "output_gain", number(&PreprocessingParams::output_gain) },
    { "sky_fraction", number(&PreprocessingParams::sky_fraction) },
  };
  return table;
}

// Steps 2-5: the localizer's parameters.
const std::map<std::string, Setter>& localizerSetters()
{
  static const std::map<std::string, Setter> table = {
    { "method",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return sequenceMethodFromString(v, &l->method); } },
    { "cost_function",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return costFunctionFromString(v, &l->cost_function); } },
    { "ring_buffer_rows", LOCALIZER_FIELD(int, ring_buffer_rows) },
    { "max_shift_px", LOCALIZER_FIELD(int, max_shift_px) },
    { "homing_max_shift_px", LOCALIZER_FIELD(int, homing_max_shift_px) },
    { "homing_max_vertical_shift_px", LOCALIZER_FIELD(int, homing_max_vertical_shift_px) },
    { "subpixel_shift",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->subpixel_shift); } },
    { "contrast_window", LOCALIZER_FIELD(int, contrast_window) },
    { "contrast_min_std", LOCALIZER_FIELD(float, contrast_min_std) },
    { "contrast_clamp", LOCALIZER_FIELD(float, contrast_clamp) },
    { "row_weight_reference", LOCALIZER_FIELD(float, row_weight_reference) },
    { "row_weight_range", LOCALIZER_FIELD(float, row_weight_range) },
    { "min_texture_ratio", LOCALIZER_FIELD(float, min_texture_ratio) },
    { "stationary_ratio", LOCALIZER_FIELD(float, stationary_ratio) },
    { "first_stop_penalty", LOCALIZER_FIELD(float, dtw.first_stop_penalty) },
    { "energy_normalized_cost",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->energy_normalized_cost); } },
    { "search_radius", LOCALIZER_FIELD(int, search_radius) },
    { "coarse_search_keyframes", LOCALIZER_FIELD(int, coarse_search_keyframes) },
    { "max_jump_ahead", LOCALIZER_FIELD(int, max_jump_ahead) },
    { "cruise_speed_frames", LOCALIZER_FIELD(int, cruise_speed_frames) },
    { "relocalization_rows", LOCALIZER_FIELD(int, relocalization_rows) },
    { "motion_prior_weight", LOCALIZER_FIELD(float, motion_prior_weight) },
    { "motion_prior_cap", LOCALIZER_FIELD(float, motion_prior_cap) },
    { "loss_needs_contradiction",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->loss_needs_contradiction); } },
    { "contradiction_chance_margin",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->contradiction_chance_margin); } },
    { "dead_reckon_while_lost",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->dead_reckon_while_lost); } },
    { "run_dead_reckoning",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->run_dead_reckoning); } },
    { "fill_frame_gaps",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->fill_frame_gaps); } },
    { "max_step", LOCALIZER_FIELD(int, dtw.max_step) },
    { "stop_penalty", LOCALIZER_FIELD(float, dtw.stop_penalty) },
    { "skip_penalty", LOCALIZER_FIELD(float, dtw.skip_penalty) },
    { "sustained_skip_penalty", LOCALIZER_FIELD(float, dtw.sustained_skip_penalty) },
    { "missing_cost", LOCALIZER_FIELD(float, dtw.missing_cost) },
    { "exclusion_radius", LOCALIZER_FIELD(int, dtw.exclusion_radius) },
    { "column_centering",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->dtw.column_centering); } },
    { "seqslam_sequence_length", LOCALIZER_FIELD(int, seqslam.sequence_length) },
    { "seqslam_min_velocity", LOCALIZER_FIELD(float, seqslam.min_velocity) },
    { "seqslam_max_velocity", LOCALIZER_FIELD(float, seqslam.max_velocity) },
    { "seqslam_velocity_step", LOCALIZER_FIELD(float, seqslam.velocity_step) },
    { "start_keyframe", LOCALIZER_FIELD(int, start_keyframe) },
    { "min_init_frames", LOCALIZER_FIELD(int, min_init_frames) },
    { "confidence_threshold", LOCALIZER_FIELD(double, confidence_threshold) },
    { "confidence_scale", LOCALIZER_FIELD(float, confidence_scale) },
    { "calibration_offset", LOCALIZER_FIELD(float, calibration_offset) },
    { "calibration_slope", LOCALIZER_FIELD(float, calibration_slope) },
    { "lost_after_frames", LOCALIZER_FIELD(int, lost_after_frames) },
    { "lost_window_frames", LOCALIZER_FIELD(int, lost_window_frames) },
    { "init_confirm_frames", LOCALIZER_FIELD(int, init_confirm_frames) },
    { "end_of_route_keyframes", LOCALIZER_FIELD(int, end_of_route_keyframes) },
    { "horizontal_fov_deg",
      [](const std::string& v, PreprocessingParams*, LocalizerParams* l) {
        double deg;
        return parseDouble(v, &deg) && ((l->horizontal_fov_rad = deg * M_PI / 180.0), true);
      } },
    { "parallel", [](const std::string& v, PreprocessingParams*, LocalizerParams* l) { return parseBool(v, &l->parallel); } },
  };
  return table;
}

std::string trim(const std::string& s)
{
  const size_t a = s.find_first_not_of(" \t\r\"'");
  if (a == std::string::npos)
    return "";
  const size_t b = s.find_last_not_of(" \t\r\"'");
  return s.substr(a, b - a + 1);
}

}  // namespace

bool applyParameter(const std::string& name, const std::string& value, PreprocessingParams* preprocessing,
                    LocalizerParams* localizer, std::string* error)
{
  const Setter* setter = nullptr;
  for (const std::map<std::string, Setter>* table : { &preprocessingSetters(), &localizerSetters() })
  {
    const auto it = table->find(name);
    if (it != table->end())
      setter = &it->second;
  }
  if (!setter)
  {
    *error = "unknown parameter '" + name + "'";
    return false;
  }
  if (!(*setter)(value, preprocessing, localizer))
  {
    *error = "parameter '" + name + "' cannot take the value '" + value + "'";
    return false;
  }
  return true;
}

namespace
{

std::vector<std::string> namesOf(const std::map<std::string, Setter>& setters)
{
  std::vector<std::string> names;
  for (const auto& entry : setters)
    names.push_back(entry.first);
  return names;
}

}  // namespace

std::vector<std::string> preprocessingParameterNames()
{
  return namesOf(preprocessingSetters());
}

std::vector<std::string> localizerParameterNames()
{
  return namesOf(localizerSetters());
}

std::vector<std::string> parameterNames()
{
  std::vector<std::string> names = preprocessingParameterNames();
  const std::vector<std::string> localizer = localizerParameterNames();
  names.insert(names.end(), localizer.begin(), localizer.end());
  std::sort(names.begin(), names.end());
  return names;
}

bool readParameterFile(const std::string& path, std::vector<ParameterEntry>* entries, std::string* error)
{
  entries->clear();
  std::ifstream in(path);
  if (!in)
  {
    *error = "cannot open parameter file '" + path + "'";
    return false;
  }
  std::string line;
  int number = 0;
  bool recorder_section = false;
  while (std::getline(in, line))
  {
    ++number;
    const std::string content = trim(line.substr(0, line.find('#')));
    if (content.empty())
      continue;
    const size_t colon = content.find(':');
    if (colon == std::string::npos)
    {
      *error = path + ":" + std::to_string(number) + ": expected 'name: value'";
      return false;
    }
    const std::string name = trim(content.substr(0, colon));
    const std::string value = trim(content.substr(colon + 1));
    const bool indented = line[0] == ' ' || line[0] == '\t';
    if (value.empty())
    {
      // A section header. The launch files' params_file has preprocessor:, map_recorder: and localizer:
      // sections; the recorder's settings do not concern the offline localizer.
      if (!indented)
        recorder_section = name == "map_recorder";
      continue;
    }
    if (!indented)
      recorder_section = false;
    if (!recorder_section)
      entries->push_back({ name, value, number });
  }
  return true;
}

bool applyParameterEntries(const std::string& path, const std::vector<ParameterEntry>& entries,
                           PreprocessingParams* preprocessing, LocalizerParams* localizer, std::string* error)
{
  std::map<std::string, int> set_on_line;  // a name given twice would otherwise silently take the last value
  for (const ParameterEntry& entry : entries)
  {
    std::string why;
    if (!applyParameter(entry.name, entry.value, preprocessing, localizer, &why))
    {
      *error = path + ":" + std::to_string(entry.line) + ": " + why;
      return false;
    }
    const auto earlier = set_on_line.emplace(entry.name, entry.line);
    if (!earlier.second)
    {
      *error = path + ":" + std::to_string(entry.line) + ": '" + entry.name + "' is already set on line " +
               std::to_string(earlier.first->second) + "; give each parameter once";
      return false;
    }
  }
  return true;
}

bool loadParameterFile(const std::string& path, PreprocessingParams* preprocessing, LocalizerParams* localizer,
                       std::string* error)
{
  std::vector<ParameterEntry> entries;
  return readParameterFile(path, &entries, error) &&
         applyParameterEntries(path, entries, preprocessing, localizer, error);
}

}  // namespace along_route_localization
