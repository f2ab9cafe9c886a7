#include "along_route_localization/parameters.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <map>
#include <set>
#include <sstream>
#include <type_traits>
#include <utility>

namespace along_route_localization
{

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

namespace
{

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

using Group = ParameterGroup;

/// A row for a number or boolean field; `field` returns a reference to it in a ParameterSet.
template <typename Field>
ParameterSpec numberRow(const char* name, Group group, double min, double max, const char* unit, const char* doc,
                        Field field)
{
  using T = typename std::remove_reference<decltype(field(std::declval<ParameterSet&>()))>::type;
  ParameterSpec spec;
  spec.name = name;
  spec.group = group;
  spec.type = std::is_same<T, bool>::value ? ParameterType::kBool :
              std::is_integral<T>::value   ? ParameterType::kInt :
                                             ParameterType::kDouble;
  spec.min = spec.type == ParameterType::kBool ? 0.0 : min;
  spec.max = spec.type == ParameterType::kBool ? 1.0 : max;
  spec.unit = unit;
  spec.doc = doc;
  spec.get_number = [field](const ParameterSet& p) {
    return static_cast<double>(field(const_cast<ParameterSet&>(p)));  // field() only reads here
  };
  spec.set_number = [field](ParameterSet* p, double value) {
    field(*p) = std::is_integral<T>::value && !std::is_same<T, bool>::value ? static_cast<T>(std::lround(value)) :
                                                                              static_cast<T>(value);
  };
  return spec;
}

ParameterSpec boolRow(const char* name, Group group, const char* doc, std::function<bool&(ParameterSet&)> field)
{
  return numberRow(name, group, 0.0, 1.0, "", doc, field);
}

ParameterSpec choiceRow(const char* name, Group group, const char* doc, std::vector<std::string> choices,
                        std::function<std::string(const ParameterSet&)> get,
                        std::function<bool(ParameterSet*, const std::string&)> set)
{
  ParameterSpec spec;
  spec.name = name;
  spec.group = group;
  spec.type = ParameterType::kChoice;
  spec.min = spec.max = 0.0;
  spec.doc = doc;
  spec.choices = std::move(choices);
  spec.get_choice = std::move(get);
  spec.set_choice = std::move(set);
  return spec;
}

/// Marks a row as the user tier (ParameterTier): the rows not marked are advanced.
ParameterSpec user(ParameterSpec spec)
{
  spec.tier = ParameterTier::kUser;
  return spec;
}

#define FIELD(expr) [](ParameterSet& p) -> decltype((p.expr)) { return p.expr; }

std::vector<ParameterSpec> makeTable()
{
  const Group pre = Group::kPreprocessor, loc = Group::kLocalizer, rec = Group::kMapRecorder,
              fol = Group::kRouteFollower;
  const double kMaxInt = 2e9;
  std::vector<ParameterSpec> t;
  // The tier of each row: user(...) marks what a user sets for the robot and the route; every other row
  // is advanced (doc/usage.md, All parameters, says why per group). A row taken out of the table goes to
  // removedParameters() below, so that params files naming it get a warning.
  // Step 1, the preprocessor (cfg/Preprocessor.cfg); stored in the map.
  t.push_back(user(numberRow("output_width", pre, 8, 1024, "px", "Width of the preprocessed image",
                             FIELD(preprocessing.output_width))));
  t.push_back(user(numberRow("output_height", pre, 4, 1024, "px", "Height of the preprocessed image",
                             FIELD(preprocessing.output_height))));
  t.push_back(user(choiceRow(
      "normalization", pre, "Normalization: patch (eq. 1), divisive (eq. 3) or none (grayscale and resize only)",
      { "patch", "divisive", "none" }, [](const ParameterSet& p) { return toString(p.preprocessing.normalization); },
      [](ParameterSet* p, const std::string& v) { return normalizationFromString(v, &p->preprocessing.normalization); })));
  t.push_back(numberRow("patch_size", pre, 2, 256, "px",
                        "eq. 1: side of the square patches (corrected to divide the output size)",
                        FIELD(preprocessing.patch_size)));
  t.push_back(numberRow("min_patch_std", pre, 0, 128, "gray levels",
                        "eq. 1: patches with a smaller std become flat 128", FIELD(preprocessing.min_patch_std)));
  t.push_back(user(numberRow("filter_window", pre, 3, 63, "px",
                             "eq. 3: side of the Gaussian window (odd; an even value is corrected)",
                             FIELD(preprocessing.filter_window))));
  t.push_back(user(numberRow("normalization_strength", pre, 0.0001, 100, "per gray level", "eq. 3: s",
                             FIELD(preprocessing.normalization_strength))));
  t.push_back(numberRow("output_gain", pre, 0.1, 255, "bytes per unit",
                        "Bytes per unit of normalized intensity: byte = 128 + gain * z",
                        FIELD(preprocessing.output_gain)));
  t.push_back(user(numberRow("sky_fraction", pre, 0, 0.95, "", "Share of the top rows set to 0 (sky blackening)",
                             FIELD(preprocessing.sky_fraction))));

  // Steps 2-5, the localizer: first those of cfg/Localizer.cfg (dynamic), then the static ones.
  t.push_back(user(choiceRow(
      "method", loc, "Sequence matching: dtw (online DTW, this package) or seqslam (straight-line baseline)",
      { "dtw", "seqslam" }, [](const ParameterSet& p) { return toString(p.localizer.method); },
      [](ParameterSet* p, const std::string& v) { return sequenceMethodFromString(v, &p->localizer.method); })));
  t.push_back(user(numberRow("ring_buffer_rows", loc, 3, 1000, "frames",
                             "K: frames in the sequence window (ring-buffer rows; at least min_init_frames)", FIELD(localizer.ring_buffer_rows))));
  t.push_back(user(numberRow("max_step", loc, 1, 16, "keyframes per frame",
                             "s: most keyframes advanced per frame, DTW steps (1,0)..(1,s)", FIELD(localizer.dtw.max_step))));
  t.push_back(user(numberRow("max_shift_px", loc, 0, 127, "px",
                             "m: horizontal shift search range in the preprocessed image (below half its width; the "
                             "localizer nodelet corrects a larger value, localize_offline refuses it)",
                             FIELD(localizer.max_shift_px))));
  t.push_back(numberRow("shift_bands", loc, 1, 16, "bands",
                        "Horizontal bands of the image each shifted on its own in the shift search (1: one shift; 2 "
                        "for a repeat beside the taught line)",
                        FIELD(localizer.shift_bands)));
  t.push_back(numberRow("max_vertical_shift_px", loc, 0, 63, "px",
                        "Vertical offsets [-V, V] at which each keyframe is also compared, px of the preprocessed "
                        "image (0: level only; 1-2 for a camera that pitches and rolls, a rover on rough ground)",
                        FIELD(localizer.max_vertical_shift_px)));
  t.push_back(user(numberRow("homing_max_shift_px", loc, 0, 127, "px",
                             "Horizontal shift range of the homing estimate (homing.h), px of the preprocessed image",
                             FIELD(localizer.homing_max_shift_px))));
  t.push_back(user(numberRow("homing_max_vertical_shift_px", loc, 0, 127, "px",
                             "Vertical shift range per column of the homing estimate (camera pitch)",
                             FIELD(localizer.homing_max_vertical_shift_px))));
  t.push_back(user(numberRow("contrast_window", loc, 1, 10000, "keyframes",
                             "n: eq. 2 half window of the contrast enhancement", FIELD(localizer.contrast_window))));
  t.push_back(user(numberRow("search_radius", loc, 1, 100000, "keyframes",
                             "Keyframes computed on each side of the predicted match while tracking (at least max_step)",
                             FIELD(localizer.search_radius))));
  t.push_back(user(numberRow("confidence_threshold", loc, 0, 1, "", "Below it a frame counts as low-confidence",
                             FIELD(localizer.confidence_threshold))));
  t.push_back(numberRow("stop_penalty", loc, 0, 10, "cost", "Cost of a DTW (1,0) stop that follows another stop",
                        FIELD(localizer.dtw.stop_penalty)));
  t.push_back(numberRow("skip_penalty", loc, 0, 10, "cost",
                        "Cost added per keyframe skipped beyond one when speeding up", FIELD(localizer.dtw.skip_penalty)));
  t.push_back(numberRow("motion_prior_weight", loc, 0, 10, "cost per row per keyframe",
                        "Cost between a match and the predicted position while tracking (0: off)",
                        FIELD(localizer.motion_prior_weight)));
  {
    ParameterSpec fov = numberRow("horizontal_fov_deg", loc, 1, 179, "deg",
                                  "Camera horizontal field of view, for the homing angle",
                                  FIELD(localizer.horizontal_fov_rad));
    fov.get_number = [](const ParameterSet& p) { return p.localizer.horizontal_fov_rad * 180.0 / M_PI; };
    fov.set_number = [](ParameterSet* p, double deg) { p->localizer.horizontal_fov_rad = deg * M_PI / 180.0; };
    t.push_back(user(fov));
  }
  t.push_back(numberRow("lost_after_frames", loc, 1, 10000, "frames",
                        "Lost (global search) when this many of the last lost_window_frames informative frames were "
                        "low-confidence",
                        FIELD(localizer.lost_after_frames)));
  t.push_back(numberRow("lost_window_frames", loc, 1, 10000, "frames",
                        "Informative frames looked back on for lost_after_frames (at least it)",
                        FIELD(localizer.lost_window_frames)));
  // Static: read once at start (params file, ~name, --set).
  t.push_back(choiceRow(
      "cost_function", loc, "Image difference: sad (sum of absolute differences) or census", { "sad", "census" },
      [](const ParameterSet& p) { return toString(p.localizer.cost_function); },
      [](ParameterSet* p, const std::string& v) { return costFunctionFromString(v, &p->localizer.cost_function); }));
  t.push_back(boolRow("subpixel_shift", loc, "Measure the shift to a fraction of a pixel",
                      FIELD(localizer.subpixel_shift)));
  t.push_back(numberRow("contrast_clamp", loc, 0.1, 100, "", "Limit of |enhanced cost| (eq. 2)",
                        FIELD(localizer.contrast_clamp)));
  t.push_back(numberRow("row_weight_reference", loc, 0.1, 100, "std",
                        "Peak (in eq. 2 stds) at which a tracking row weighs 1", FIELD(localizer.row_weight_reference)));
  t.push_back(numberRow("row_weight_range", loc, 0, 0.99, "",
                        "Row weights lie in 1 -/+ this (0: every row weighs 1)", FIELD(localizer.row_weight_range)));
  t.push_back(numberRow("min_texture_ratio", loc, 0, 4, "",
                        "Featureless below this share of the map's median keyframe texture energy",
                        FIELD(localizer.min_texture_ratio)));
  t.push_back(numberRow("stationary_ratio", loc, 0, 1, "",
                        "Same view (camera stood still) below this share of the map's median keyframe change (0: off)",
                        FIELD(localizer.stationary_ratio)));
  t.push_back(numberRow("first_stop_penalty", loc, 0, 10, "cost",
                        "Cost of a DTW (1,0) stop right after a move: breaks ties toward the nominal speed",
                        FIELD(localizer.dtw.first_stop_penalty)));
  t.push_back(numberRow("sustained_skip_penalty", loc, 0, 10, "cost",
                        "As skip_penalty, for a skip that follows another skip", FIELD(localizer.dtw.sustained_skip_penalty)));
  t.push_back(numberRow("missing_cost", loc, 0, 10, "cost", "Cost of a keyframe a row did not compute (outside its band)",
                        FIELD(localizer.dtw.missing_cost)));
  // At least 1: with 0 the second-best end is a neighbour of the best, the margin vanishes and the track is
  // reported lost nearly all the time (doc/evaluation_history.md, Where each default came from).
  t.push_back(numberRow("exclusion_radius", loc, 1, 1000000, "keyframes",
                        "Keyframes around the best end ignored for the second-best cost", FIELD(localizer.dtw.exclusion_radius)));
  t.push_back(boolRow("column_centering", loc, "Subtract each keyframe's mean cost over the window before the DTW",
                      FIELD(localizer.dtw.column_centering)));
  t.push_back(boolRow("energy_normalized_cost", loc,
                      "Divide each SAD by the two images' texture energies (step 2b)",
                      FIELD(localizer.energy_normalized_cost)));
  t.push_back(numberRow("coarse_search_keyframes", loc, 0, kMaxInt, "keyframes",
                        "Maps of at least this many keyframes are searched globally on halved images (0: never)",
                        FIELD(localizer.coarse_search_keyframes)));
  t.push_back(numberRow("max_jump_ahead", loc, 0, 1000000, "keyframes",
                        "While tracking, the new match lies at most max_step + this ahead of the last",
                        FIELD(localizer.max_jump_ahead)));
  t.push_back(numberRow("cruise_speed_frames", loc, 0, 1000000, "frames",
                        "Frames over which the robot's cruise speed is averaged (0: the nominal speed)",
                        FIELD(localizer.cruise_speed_frames)));
  t.push_back(numberRow("relocalization_rows", loc, 0, 1000, "frames",
                        "Recent frames searched over the whole map after a loss and while they do not support the track (0: neither)",
                        FIELD(localizer.relocalization_rows)));
  t.push_back(numberRow("motion_prior_cap", loc, 0, 1000, "keyframes",
                        "Distance beyond which the motion prior's cost stays flat", FIELD(localizer.motion_prior_cap)));
  t.push_back(boolRow("run_dead_reckoning", loc,
                      "Through a run of identical keyframes, report the keyframe reached at the entry speed",
                      FIELD(localizer.run_dead_reckoning)));
  t.push_back(user(boolRow("fill_frame_gaps", loc, "Frames missed (a gap in the stamps) become rows without evidence",
                      FIELD(localizer.fill_frame_gaps))));
  t.push_back(numberRow("seqslam_sequence_length", loc, 2, 1000, "frames", "SeqSLAM baseline: ds, frames per sequence",
                        FIELD(localizer.seqslam.sequence_length)));
  t.push_back(numberRow("seqslam_min_velocity", loc, -100, 100, "keyframes per frame",
                        "SeqSLAM baseline: slowest velocity tried", FIELD(localizer.seqslam.min_velocity)));
  t.push_back(numberRow("seqslam_max_velocity", loc, -100, 100, "keyframes per frame",
                        "SeqSLAM baseline: fastest velocity tried (at least seqslam_min_velocity)",
                        FIELD(localizer.seqslam.max_velocity)));
  t.push_back(numberRow("seqslam_velocity_step", loc, 0.001, 100, "keyframes per frame",
                        "SeqSLAM baseline: step between velocities tried", FIELD(localizer.seqslam.velocity_step)));
  t.push_back(user(numberRow("start_keyframe", loc, -1, kMaxInt, "keyframe",
                             "Where the robot starts (-1: unknown, a global search first)", FIELD(localizer.start_keyframe))));
  t.push_back(user(boolRow("detect_kidnapping", loc,
                           "While tracking, look for the robot elsewhere: refute a known start, move the track on the "
                           "newest frames (false: it only moves as it drives, e.g. a closed-loop repeat, and a loss searches "
                           "only where it could have driven)",
                           FIELD(localizer.detect_kidnapping))));
  t.push_back(numberRow("min_init_frames", loc, 1, 10000, "frames", "Frames before the first global answer",
                        FIELD(localizer.min_init_frames)));
  t.push_back(numberRow("init_confirm_frames", loc, 1, 10000, "frames",
                        "Consecutive confident, advancing global answers before tracking starts",
                        FIELD(localizer.init_confirm_frames)));
  t.push_back(numberRow("confidence_scale", loc, 0.001, 1000, "cost per row",
                        "Cost margin per row that maps to confidence 1 - 1/e", FIELD(localizer.confidence_scale)));
  t.push_back(numberRow("calibration_offset", loc, -50, 50, "",
                        "The published confidence is sigma(offset + slope * c), the probability of being within one "
                        "keyframe (fitted by cross_validate)", FIELD(localizer.calibration_offset)));
  t.push_back(numberRow("calibration_slope", loc, 0, 1000, "",
                        "Slope of the confidence calibration (0: publish c itself)",
                        FIELD(localizer.calibration_slope)));
  t.push_back(boolRow("posterior_confidence", loc,
                      "c is the route posterior's mass within one keyframe of the answer (false: the DTW's margin "
                      "confidence)",
                      FIELD(localizer.posterior_confidence)));
  t.push_back(numberRow("posterior_cost_scale", loc, 0.0001, 100, "cost",
                        "Route posterior: a keyframe's likelihood is exp(-(cost - least cost) / this)",
                        FIELD(localizer.posterior.cost_scale)));
  t.push_back(numberRow("posterior_speed_change", loc, 0, 1, "per frame",
                        "Route posterior: probability that the speed changes by half a keyframe per frame",
                        FIELD(localizer.posterior.speed_change)));
  t.push_back(numberRow("posterior_jump", loc, 0, 1, "per frame",
                        "Route posterior: probability that the robot is anywhere on the route (carried elsewhere)",
                        FIELD(localizer.posterior.jump)));
  t.push_back(numberRow("posterior_start_doubt", loc, 0, 1, "",
                        "Route posterior: share of the belief a known start leaves spread over the route",
                        FIELD(localizer.posterior.start_doubt)));
  t.push_back(boolRow("loss_needs_contradiction", loc,
                      "When the loss detection fires, coast and lose the track only on evidence for another place",
                      FIELD(localizer.loss_needs_contradiction)));
  t.push_back(numberRow("contradiction_margin_share", loc, 0, 10, "",
                        "Another place contradicts the track only by more than this share of the map's chance "
                        "margin (0: by its place confidence alone)",
                        FIELD(localizer.contradiction_margin_share)));
  t.push_back(boolRow("dead_reckon_while_lost", loc,
                      "While lost, answer the dead-reckoned keyframe instead of the global search's guess",
                      FIELD(localizer.dead_reckon_while_lost)));
  t.push_back(user(numberRow("end_of_route_keyframes", loc, 0, 1000000, "keyframes",
                             "A match this close to the last keyframe reports end_of_route",
                             FIELD(localizer.end_of_route_keyframes))));
  t.push_back(boolRow("parallel", loc, "Spread global searches over the cores", FIELD(localizer.parallel)));

  // The map recorder's keyframe policy (cfg/MapRecorder.cfg).
  t.push_back(user(numberRow("every_nth", rec, 1, 1000, "frames", "Keep every n-th frame (1: every frame)",
                             FIELD(keyframes.every_nth))));
  t.push_back(user(numberRow("min_time_gap", rec, 0, 3600, "s",
                             "Minimum time since the last keyframe, from the header stamps (0: off)",
                             FIELD(keyframes.min_time_gap_s))));
  t.push_back(user(numberRow("min_appearance_change", rec, 0, 255, "gray levels",
                             "Minimum mean absolute byte difference to the last keyframe (0: off)",
                             FIELD(keyframes.min_appearance_change))));
  t.push_back(user(numberRow("min_distance", rec, 0, 10000, "m",
                             "Minimum distance travelled since the last keyframe, from the odom topic (0: off)",
                             FIELD(keyframes.min_distance_m))));

  // The route follower's controller and safety thresholds (cfg/RouteFollower.cfg; route_follower.h).
  t.push_back(user(numberRow("homing_gain", fol, 0, 20, "rad/s per rad", "Turn rate per homing angle",
                             FIELD(follower.homing_gain))));
  t.push_back(user(numberRow("max_homing_turn_rate", fol, 0, 10, "rad/s", "Bound of the homing term |gain x angle|",
                             FIELD(follower.max_homing_turn_rps))));
  t.push_back(numberRow("homing_time_constant", fol, 0, 10, "s",
                        "Low-pass time constant of the homing angle (0: none)", FIELD(follower.homing_time_constant_s)));
  t.push_back(user(numberRow("speed_factor", fol, 0, 5, "", "Forward speed (and taught turn rate) = taught x this",
                             FIELD(follower.speed_factor))));
  t.push_back(user(numberRow("min_confidence", fol, 0, 1, "",
                             "A localization whose confidence (the probability of being within one keyframe) is below "
                             "this counts as low",
                             FIELD(follower.min_confidence))));
  t.push_back(numberRow("slow_after_frames", fol, 1, 1000, "frames",
                        "Low-confidence localizations in a row before slowing", FIELD(follower.slow_after_frames)));
  t.push_back(numberRow("stop_after_frames", fol, 1, 1000, "frames",
                        "Low-confidence localizations in a row before stopping (at least slow_after_frames)",
                        FIELD(follower.stop_after_frames)));
  t.push_back(numberRow("slow_factor", fol, 0, 1, "", "Fraction of the speed while slowing (and creeping)",
                        FIELD(follower.slow_factor)));
  t.push_back(user(numberRow("recovery_distance", fol, 0, 1000, "m",
                             "After a stop for low confidence or a loss, creep on (slow_factor, no homing) at most "
                             "this far to bring new views (0: stop at once)",
                             FIELD(follower.recovery_distance_m))));
  t.push_back(user(numberRow("watchdog_timeout", fol, 0.01, 60, "s", "Stop when no localization came for this long",
                             FIELD(follower.watchdog_timeout_s))));
  t.push_back(user(numberRow("max_linear_accel", fol, 0.001, 100, "m/s^2",
                             "Bound of the rise of the forward speed (speeding up)",
                             FIELD(follower.max_linear_accel))));
  // At least 0.1: a stop (~stop, the watchdog, lost) is bounded by them; at 0.001 m/s^2 a robot at 1 m/s
  // took 1000 s to stop after ~stop.
  t.push_back(user(numberRow("max_linear_decel", fol, 0.1, 100, "m/s^2",
                             "Bound of the slowing of the forward speed (braking, a stop)",
                             FIELD(follower.max_linear_decel))));
  t.push_back(user(numberRow("max_angular_accel", fol, 0.1, 100, "rad/s^2", "Bound of the change of the turn rate",
                             FIELD(follower.max_angular_accel))));
  return t;
}

#undef FIELD

/// Parses `text` for `spec` without a range check.
bool parseValue(const ParameterSpec& spec, const std::string& text, double* number)
{
  bool flag = false;
  switch (spec.type)
  {
    case ParameterType::kInt:
    {
      int i = 0;
      if (!parseInt(text, &i))
        return false;
      *number = i;
      return true;
    }
    case ParameterType::kDouble:
      return parseDouble(text, number);
    case ParameterType::kBool:
      if (!parseBool(text, &flag))
        return false;
      *number = flag ? 1.0 : 0.0;
      return true;
    case ParameterType::kChoice:
      break;
  }
  return false;
}

bool setUnchecked(const ParameterSpec& spec, const std::string& text, ParameterSet* params)
{
  if (spec.type == ParameterType::kChoice)
    return spec.set_choice(params, text);
  double number = 0.0;
  if (!parseValue(spec, text, &number))
    return false;
  spec.set_number(params, number);
  return true;
}

std::string formatNumber(double value, bool integer = false)
{
  char text[64];
  if (integer && std::abs(value) < 1e15)
    std::snprintf(text, sizeof(text), "%.0f", value);
  else
    std::snprintf(text, sizeof(text), "%.6g", value);
  return text;
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

std::string toString(ParameterGroup group)
{
  switch (group)
  {
    case ParameterGroup::kPreprocessor:
      return "preprocessor";
    case ParameterGroup::kLocalizer:
      return "localizer";
    case ParameterGroup::kMapRecorder:
      return "map_recorder";
    case ParameterGroup::kRouteFollower:
      return "route_follower";
  }
  return "unknown";
}

std::string toString(ParameterTier tier)
{
  return tier == ParameterTier::kUser ? "user" : "advanced";
}

const std::vector<RemovedParameter>& removedParameters()
{
  static const std::vector<RemovedParameter> removed = {
    { "contrast_min_std", formatNumber(kContrastMinStd),
      "kContrastMinStd, contrast_enhancement.h: the eq. 2 std's floor only keeps a flat difference vector from "
      "dividing by zero" },
  };
  return removed;
}

std::string removedParameterSentence(const std::string& name)
{
  for (const RemovedParameter& removed : removedParameters())
    if (removed.name == name)
      return name + " was removed in this version; it is now fixed at " + removed.fixed_at + " (" + removed.why +
             ")";
  return "";
}

std::string ParameterSpec::valueText(const ParameterSet& params) const
{
  switch (type)
  {
    case ParameterType::kChoice:
      return get_choice(params);
    case ParameterType::kBool:
      return get_number(params) != 0.0 ? "true" : "false";
    default:
      return formatNumber(get_number(params), type == ParameterType::kInt);
  }
}

std::string ParameterSpec::rangeText() const
{
  if (type == ParameterType::kBool)
    return "true | false";
  std::string text;
  if (type == ParameterType::kChoice)
  {
    for (const std::string& choice : choices)
      text += (text.empty() ? "" : " | ") + choice;
    return text;
  }
  text = formatNumber(min, type == ParameterType::kInt) + " .. " + formatNumber(max, type == ParameterType::kInt);
  return unit.empty() ? text : text + " " + unit;
}

bool ParameterSpec::inRange(double value) const
{
  return value >= min && value <= max && (type != ParameterType::kInt || value == std::floor(value));
}

const std::vector<ParameterSpec>& parameterTable()
{
  static const std::vector<ParameterSpec> table = makeTable();
  return table;
}

const ParameterSpec* findParameter(const std::string& name)
{
  for (const ParameterSpec& spec : parameterTable())
    if (spec.name == name)
      return &spec;
  return nullptr;
}

std::string correctNumber(const ParameterSpec& spec, double given, double fallback, double* used)
{
  if (spec.inRange(given))
  {
    *used = given;
    return "";
  }
  std::ostringstream sentence;
  const bool integer = spec.type == ParameterType::kInt;
  sentence << spec.name << " " << formatNumber(given, integer && given == std::floor(given));
  if (!std::isfinite(given))
  {
    *used = fallback;
    sentence << " is not a number in " << spec.rangeText() << "; keeping " << formatNumber(fallback, integer);
    return sentence.str();
  }
  *used = std::max(spec.min, std::min(spec.max, spec.type == ParameterType::kInt ? std::round(given) : given));
  sentence << " is outside " << spec.rangeText() << "; using " << formatNumber(*used, integer);
  return sentence.str();
}

std::string setParameterChecked(const std::string& name, const std::string& value, ParameterSet* params,
                                bool* refused)
{
  if (refused)
    *refused = true;
  const ParameterSpec* spec = findParameter(name);
  if (!spec && !removedParameterSentence(name).empty())
    return removedParameterSentence(name) + "; the value given is ignored";
  if (!spec)
  {
    return "unknown parameter '" + name + "' refused" + didYouMean(name);
  }
  const std::string keeping = "; keeping " + spec->valueText(*params);
  if (spec->type == ParameterType::kChoice)
  {
    if (!spec->set_choice(params, value))
      return name + " '" + value + "' is not one of " + spec->rangeText() + keeping;
    if (refused)
      *refused = false;
    return "";
  }
  double number = 0.0;
  if (!parseValue(*spec, value, &number))
    return name + " '" + value + "' is not " +
           (spec->type == ParameterType::kBool ? std::string("true or false") :
            spec->type == ParameterType::kInt  ? "an integer in " + spec->rangeText() :
                                                 "a number in " + spec->rangeText()) +
           keeping;
  double used = number;
  const std::string sentence = correctNumber(*spec, number, spec->get_number(*params), &used);
  spec->set_number(params, used);
  if (refused)
    *refused = false;
  return sentence;
}

std::string checkRanges(ParameterGroup group, const ParameterSet& params)
{
  for (const ParameterSpec& spec : parameterTable())
  {
    if (spec.group != group || spec.type == ParameterType::kChoice || spec.type == ParameterType::kBool)
      continue;
    // The value as stored: a float field holds the nearest float to what was given, which may lie just
    // outside a bound that has no exact float (0.99 is stored as 0.9900000095), so each bound is compared
    // as stored too.
    const double value = spec.get_number(params);
    const auto stored = [&](double bound) {
      return std::abs(bound) < 3.0e38 ? static_cast<double>(static_cast<float>(bound)) : bound;
    };
    const bool within_stored_bounds = spec.type == ParameterType::kDouble &&
                                      value >= std::min(spec.min, stored(spec.min)) &&
                                      value <= std::max(spec.max, stored(spec.max));
    if (!spec.inRange(value) && !within_stored_bounds)
      return spec.name + " must be in " + spec.rangeText() + ", got " +
             formatNumber(value, spec.type == ParameterType::kInt && value == std::floor(value));
  }
  return "";
}

std::string parameterHelp(const std::vector<ParameterGroup>& groups, bool with_advanced,
                          const std::string& how_to_list)
{
  std::ostringstream text;
  const auto rows = [&text](ParameterGroup group, ParameterTier tier) {
    for (const ParameterSpec& spec : parameterTable())
      if (spec.group == group && spec.tier == tier)
        text << "    " << spec.name << " = " << spec.defaultText() << "  (" << spec.rangeText() << ")\n"
             << "        " << spec.doc << "\n";
  };
  size_t advanced = 0;
  for (const ParameterGroup group : groups)
  {
    text << "  " << toString(group) << ":\n";
    rows(group, ParameterTier::kUser);
    advanced += parameterNamesOf(group, ParameterTier::kAdvanced).size();
    if (with_advanced && !parameterNamesOf(group, ParameterTier::kAdvanced).empty())
    {
      text << "  " << toString(group) << ", advanced:\n";
      rows(group, ParameterTier::kAdvanced);
    }
  }
  if (!with_advanced && advanced > 0)
    text << "  and " << advanced << " advanced parameters, not shown (estimator internals, tie-breaking costs,\n"
         << "  calibration, the SeqSLAM baseline's, ablation switches): " << how_to_list << " lists them\n";
  return text.str();
}

std::vector<std::string> parameterNamesOf(ParameterGroup group, ParameterTier tier)
{
  std::vector<std::string> names;
  for (const ParameterSpec& spec : parameterTable())
    if (spec.group == group && spec.tier == tier)
      names.push_back(spec.name);
  return names;
}

std::vector<std::string> similarParameterNames(const std::string& name)
{
  // Levenshtein distance up to 2, or one name containing the other.
  const auto distance = [](const std::string& a, const std::string& b) {
    std::vector<size_t> row(b.size() + 1);
    for (size_t j = 0; j <= b.size(); ++j)
      row[j] = j;
    for (size_t i = 1; i <= a.size(); ++i)
    {
      size_t diagonal = row[0];
      row[0] = i;
      for (size_t j = 1; j <= b.size(); ++j)
      {
        const size_t above = row[j];
        row[j] = std::min({ row[j] + 1, row[j - 1] + 1, diagonal + (a[i - 1] == b[j - 1] ? 0 : 1) });
        diagonal = above;
      }
    }
    return row[b.size()];
  };
  std::vector<std::string> similar;
  for (const ParameterSpec& spec : parameterTable())
    if (distance(name, spec.name) <= 2 ||
        (name.size() >= 4 && (spec.name.find(name) != std::string::npos || name.find(spec.name) != std::string::npos)))
      similar.push_back(spec.name);
  std::sort(similar.begin(), similar.end());
  return similar;
}

std::string didYouMean(const std::string& name, bool localizing_only)
{
  std::string text;
  for (const std::string& other : similarParameterNames(name))
  {
    const ParameterGroup group = findParameter(other)->group;
    if (!localizing_only || group == ParameterGroup::kPreprocessor || group == ParameterGroup::kLocalizer)
      text += " " + other;
  }
  return text.empty() ? text : " (did you mean" + text + "?)";
}

bool applyParameter(const std::string& name, const std::string& value, PreprocessingParams* preprocessing,
                    LocalizerParams* localizer, std::string* error)
{
  const ParameterSpec* spec = findParameter(name);
  if (!spec && !removedParameterSentence(name).empty())
  {
    *error = removedParameterSentence(name);
    return false;
  }
  if (!spec || spec->group == ParameterGroup::kMapRecorder || spec->group == ParameterGroup::kRouteFollower)
  {
    *error = "unknown parameter '" + name + "'" + (spec ? std::string() : didYouMean(name, true));
    return false;
  }
  ParameterSet params;
  params.preprocessing = *preprocessing;
  params.localizer = *localizer;
  if (!setUnchecked(*spec, value, &params))
  {
    *error = "parameter '" + name + "' cannot take the value '" + value + "'";
    return false;
  }
  *preprocessing = params.preprocessing;
  *localizer = params.localizer;
  return true;
}

namespace
{

std::vector<std::string> namesOf(ParameterGroup group)
{
  std::vector<std::string> names;
  for (const ParameterSpec& spec : parameterTable())
    if (spec.group == group)
      names.push_back(spec.name);
  std::sort(names.begin(), names.end());
  return names;
}

}  // namespace

std::vector<std::string> preprocessingParameterNames()
{
  return namesOf(ParameterGroup::kPreprocessor);
}

std::vector<std::string> localizerParameterNames()
{
  return namesOf(ParameterGroup::kLocalizer);
}

std::vector<std::string> parameterNames()
{
  std::vector<std::string> names = preprocessingParameterNames();
  const std::vector<std::string> localizer = localizerParameterNames();
  names.insert(names.end(), localizer.begin(), localizer.end());
  std::sort(names.begin(), names.end());
  return names;
}

const std::set<std::string>& nodeletSettingNames(ParameterGroup group)
{
  static const std::set<std::string> preprocessor = { "queue_size", "image_transport" };
  static const std::set<std::string> localizer = { "map",       "debug_image_scale", "min_rate",
                                                   "max_rate",  "image_transport",   "diagnostic_period",
                                                   "report_input_buffer", "motion_type" };
  static const std::set<std::string> recorder = { "map",        "autostart",       "flush_period", "max_queue",
                                                  "queue_size", "image_transport", "motion_type" };
  static const std::set<std::string> follower = { "map", "autostart", "control_rate" };
  switch (group)
  {
    case ParameterGroup::kPreprocessor:
      return preprocessor;
    case ParameterGroup::kLocalizer:
      return localizer;
    case ParameterGroup::kMapRecorder:
      return recorder;
    case ParameterGroup::kRouteFollower:
      break;
  }
  return follower;
}

namespace
{

/// Whether the entries of `section` are the localizing nodelets' (a flat file's are).
bool localizingSection(const std::string& section)
{
  return section.empty() || section == toString(ParameterGroup::kPreprocessor) ||
         section == toString(ParameterGroup::kLocalizer);
}

/// "" unless the entry is a known parameter under the section of a nodelet that does not read it; then
/// the sentence saying where it belongs.
std::string misplacedSentence(const ParameterEntry& entry)
{
  const ParameterSpec* spec = findParameter(entry.name);
  if (entry.section.empty() || !spec || toString(spec->group) == entry.section)
    return std::string();
  return "'" + entry.name + "' is the " + toString(spec->group) + "'s parameter but is under " + entry.section +
         ":, where the launch files set it for the " + entry.section + ", which does not read it: move it under " +
         toString(spec->group) + ":";
}

/// Whether the entry is one of its section's nodelet settings (nodeletSettingNames).
bool isNodeletSetting(const ParameterEntry& entry)
{
  for (const ParameterGroup group : { ParameterGroup::kPreprocessor, ParameterGroup::kLocalizer,
                                      ParameterGroup::kMapRecorder, ParameterGroup::kRouteFollower })
    if (toString(group) == entry.section)
      return nodeletSettingNames(group).count(entry.name) > 0;
  return false;
}

}  // namespace

bool readParameterFile(const std::string& path, std::vector<ParameterEntry>* entries, std::string* error)
{
  entries->clear();
  std::ifstream in(path);
  if (!in)
  {
    *error = "cannot open parameter file '" + path + "'";
    return false;
  }
  // The launch files load the same file with rosparam, which reads YAML: what YAML reads otherwise (a section
  // of another name, flow style, an indentation YAML refuses) is an error here, not a different meaning.
  static const std::set<std::string> kSections = { "preprocessor", "localizer", "map_recorder", "route_follower" };
  std::string line;
  int number = 0;
  // Once a section has begun, entries at the start of a line are refused: the last section stays open to
  // the end, and before the first one every entry is such a flat one.
  std::string section;
  size_t section_indent = std::string::npos;  // of the open section's entries, once its first one is read
  std::set<std::string> sections_seen;
  const auto flatAmongSections = [](const std::string& name) {
    return "'" + name + "' is at the start of a line in a file with sections: YAML (the launch files) reads it as " +
           "no section's, which no nodelet reads; indent it under its section (or give no section at all)";
  };
  const auto fail = [&](const std::string& why) {
    entries->clear();
    *error = path + ":" + std::to_string(number) + ": " + why;
    return false;
  };
  while (std::getline(in, line))
  {
    ++number;
    if (number == 1 && line.compare(0, 3, "\xEF\xBB\xBF") == 0)
      line.erase(0, 3);  // a UTF-8 byte-order mark (some editors write one): YAML skips it too
    const std::string content = trim(line.substr(0, line.find('#')));
    if (content.empty())
      continue;
    const size_t indent = line.find_first_not_of(' ');
    if (line[indent] == '\t')
      return fail("a tab in the indentation (YAML, which the launch files read the file as, allows spaces only)");
    const size_t colon = content.find(':');
    if (colon == std::string::npos)
      return fail("expected 'name: value'");
    const std::string name = trim(content.substr(0, colon));
    const std::string value = trim(content.substr(colon + 1));
    const bool indented = indent > 0;
    if (!value.empty() && (value[0] == '{' || value[0] == '['))
      return fail("'" + name + ": " + value + "' is YAML's flow style, not read here: write one 'name: value' per line" +
                  (value[0] == '{' ? " under '" + name + ":'" : std::string()));
    if (value.empty())
    {
      // A section header. The launch files' params_file has preprocessor:, map_recorder:, localizer: and
      // route_follower: sections; the recorder's and the follower's settings do not concern the localizer.
      if (indented || !kSections.count(name))
        return fail("'" + name + ":' has no value and is not a section the launch files read (" +
                    "preprocessor:, localizer:, map_recorder:, route_follower:, each at the start of a line)");
      if (sections_seen.empty() && !entries->empty())  // the first section, after flat entries
      {
        number = entries->front().line;
        return fail(flatAmongSections(entries->front().name));
      }
      if (!sections_seen.insert(name).second)
        return fail("'" + name + ":' appears a second time (YAML keeps only the last one): give each section once");
      section_indent = std::string::npos;
      section = name;
      continue;
    }
    if (!indented)
    {
      if (!sections_seen.empty())
        return fail(flatAmongSections(name));
      // else a flat file's entry (no section so far): localize_offline's own form
    }
    else if (sections_seen.empty())
      return fail("'" + name + "' is indented but under no section: indent entries only under preprocessor:, "
                  "localizer:, map_recorder: or route_follower:");
    else if (section_indent == std::string::npos)
      section_indent = indent;
    else if (indent != section_indent)
      return fail("'" + name + "' is indented by " + std::to_string(indent) + " spaces, the entries above it by " +
                  std::to_string(section_indent) + " (YAML refuses that)");
    entries->push_back({ name, value, number, section });
  }
  if (in.bad())  // e.g. a folder: it opens, but reading it fails
  {
    entries->clear();
    *error = "cannot read parameter file '" + path + "' (a folder, or a read error)";
    return false;
  }
  return true;
}

bool applyParameterEntries(const std::string& path, const std::vector<ParameterEntry>& entries,
                           PreprocessingParams* preprocessing, LocalizerParams* localizer, std::string* error)
{
  std::map<std::string, int> set_on_line;  // a name given twice would otherwise silently take the last value
  for (const ParameterEntry& entry : entries)
  {
    if (!localizingSection(entry.section))
      continue;
    std::string why = misplacedSentence(entry);
    if (!why.empty() || !applyParameter(entry.name, entry.value, preprocessing, localizer, &why))
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

bool applyParameterEntriesChecked(const std::string& path, const std::vector<ParameterEntry>& entries,
                                  PreprocessingParams* preprocessing, LocalizerParams* localizer,
                                  std::vector<std::string>* warnings, std::string* error)
{
  std::map<std::string, int> set_on_line;
  for (const ParameterEntry& entry : entries)
  {
    // The recorder's and the follower's sections are other nodelets' namespaces: a name once in each is fine.
    const std::string key = (localizingSection(entry.section) ? std::string() : entry.section + "/") + entry.name;
    const auto earlier = set_on_line.emplace(key, entry.line);
    if (!earlier.second)
    {
      *error = path + ":" + std::to_string(entry.line) + ": '" + entry.name + "' is already set on line " +
               std::to_string(earlier.first->second) + "; give each parameter once";
      return false;
    }
  }
  ParameterSet params;
  params.preprocessing = *preprocessing;
  params.localizer = *localizer;
  ParameterSet others;  // the recorder's and the follower's sections: checked, not used here
  for (const ParameterEntry& entry : entries)
  {
    const ParameterSpec* spec = findParameter(entry.name);
    std::string sentence = misplacedSentence(entry);
    if (!sentence.empty())
      sentence += "; ignored";
    else if (isNodeletSetting(entry))
      sentence.clear();  // the nodelet's own (a queue, a transport, a rate): right there, of no use offline
    else if (!localizingSection(entry.section))
      sentence = setParameterChecked(entry.name, entry.value, &others);
    else if (spec && (spec->group == ParameterGroup::kMapRecorder || spec->group == ParameterGroup::kRouteFollower))
      sentence = "'" + entry.name + "' is the " +
                 (spec->group == ParameterGroup::kMapRecorder ? "map recorder" : "route follower") +
                 "'s parameter; ignored here";
    else
      sentence = setParameterChecked(entry.name, entry.value, &params);
    if (!sentence.empty())
      warnings->push_back(path + ":" + std::to_string(entry.line) + ": " + sentence);
  }
  // The combinations, corrected as the preprocessor nodelet corrects them from the same file.
  for (const std::string& sentence : params.preprocessing.correctCombinations())
    warnings->push_back(path + ": " + sentence);
  *preprocessing = params.preprocessing;
  *localizer = params.localizer;
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
