// Parameters by name: the one table of every parameter users set (params.yaml, command line,
// dynamic_reconfigure) of the preprocessor, localizer, map recorder and route follower: its name, the field it sets, its working range, unit, meaning and tier. Defaults are the
// fields' initializers; validate() checks the ranges of this table; the .cfg files are checked against it
// (test_reconfigure).
#ifndef ALONG_ROUTE_LOCALIZATION_PARAMETERS_H
#define ALONG_ROUTE_LOCALIZATION_PARAMETERS_H

#include <set>
#include <string>
#include <vector>

#include <functional>

#include "along_route_localization/localizer.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_follower.h"
#include "along_route_localization/route_map.h"

namespace along_route_localization
{

/// The whole of `text` as a number (std::stod; "12abc" is not 12, "nan" and "inf" are numbers). False when it
/// is not.
bool parseDouble(const std::string& text, double* value);
/// The whole of `text` as an integer (parseDouble, a whole number within +-2e9). False when it is not.
bool parseInt(const std::string& text, int* value);

/// Whose parameter: the preprocessor's (stored in the map), the localizer's, the map recorder's or the
/// route follower's.
enum class ParameterGroup
{
  kPreprocessor,
  kLocalizer,
  kMapRecorder,
  kRouteFollower
};
std::string toString(ParameterGroup group);

/// Who sets it. kUser: what a user sets for the robot and the route, each a physical quantity or a choice
/// (K, s, m, n, the field of view, where the route starts and ends, ...); `--help`, the README and the
/// .cfg's top level show these. kAdvanced: estimator internals, tie-breaking costs, calibration, the
/// SeqSLAM baseline's, ablation switches, chosen by the evaluation (doc/usage.md, All parameters, says why
/// per group); listed by `--help-advanced`, doc/usage.md and the .cfg's collapsed group "advanced".
enum class ParameterTier
{
  kUser,
  kAdvanced
};
std::string toString(ParameterTier tier);

enum class ParameterType
{
  kInt,
  kDouble,
  kBool,
  kChoice  ///< one of a few names
};

/// Every parameter the table sets, at its default when default-constructed.
struct ParameterSet
{
  PreprocessingParams preprocessing;
  LocalizerParams localizer;
  KeyframePolicy keyframes;
  RouteFollowerParams follower;
};

/// One row of the parameter table.
struct ParameterSpec
{
  std::string name;
  ParameterGroup group;
  ParameterTier tier = ParameterTier::kAdvanced;  ///< set per row in the table (makeTable)
  ParameterType type;
  double min, max;                   ///< kInt, kDouble: the working range, both ends included
  std::string unit;                  ///< of the value as users give it; "" when it has none
  std::string doc;                   ///< what it is, one line
  std::vector<std::string> choices;  ///< kChoice: the names it takes
  std::function<double(const ParameterSet&)> get_number;            ///< kInt, kDouble, kBool (1 / 0)
  std::function<void(ParameterSet*, double)> set_number;            ///< kInt, kDouble, kBool
  std::function<std::string(const ParameterSet&)> get_choice;       ///< kChoice
  std::function<bool(ParameterSet*, const std::string&)> set_choice;///< kChoice; false for another name

  /// The value in `params` as users write it ("30", "0.02", "true", "dtw").
  std::string valueText(const ParameterSet& params) const;
  /// The value of a default-constructed ParameterSet.
  std::string defaultText() const { return valueText(ParameterSet()); }
  /// "3 .. 1000 frames", "dtw | seqslam", "true | false".
  std::string rangeText() const;
  /// Whether a number is in the working range (an integer, for kInt).
  bool inRange(double value) const;
};

/// The table, in a fixed order (grouped, then as the .cfg files list them).
const std::vector<ParameterSpec>& parameterTable();
/// The row called `name`, or nullptr.
const ParameterSpec* findParameter(const std::string& name);

/// `given` for `spec` (a number) corrected into its working range: the nearest end of it, rounded for
/// kInt; `fallback` for a value that is not a number. Returns "" when *used == given, otherwise the
/// sentence saying so: "ring_buffer_rows -3 is outside 3 .. 1000 frames; using 3".
std::string correctNumber(const ParameterSpec& spec, double given, double fallback, double* used);

/// Sets `name` from its text as a user gave it: a number outside the working range is set to the nearest
/// end of it (correctNumber); an unknown name, a value that does not parse or a name not among the
/// choices leaves every parameter as it was. Returns "" when the value was taken as given, otherwise a
/// sentence naming the parameter, the value given and the value used; *refused (optional) is set when
/// nothing was set.
std::string setParameterChecked(const std::string& name, const std::string& value, ParameterSet* params,
                                bool* refused = nullptr);

/// validate()'s range check: "" when every parameter of `group` is in its working range, otherwise
/// "ring_buffer_rows must be in 3 .. 1000 frames, got 1" for the first that is not.
std::string checkRanges(ParameterGroup group, const ParameterSet& params);

/// The table as text for --help: for each parameter of the groups, "name  default  range unit" then its
/// doc, indented. Only the user tier unless `with_advanced`; then each group's advanced rows follow its
/// user rows under "<group>, advanced:". Without them, a last line says how many advanced rows of the
/// groups there are and how to list them (`how_to_list`, e.g. "localize_offline --help-advanced").
std::string parameterHelp(const std::vector<ParameterGroup>& groups, bool with_advanced = false,
                          const std::string& how_to_list = "--help-advanced");

/// The rows of `group` in `tier`, in table order.
std::vector<std::string> parameterNamesOf(ParameterGroup group, ParameterTier tier);

/// A parameter this version no longer has: its name, the value it is now fixed at and why.
struct RemovedParameter
{
  std::string name, fixed_at, why;
};
/// Every parameter an earlier version had and this one removed.
const std::vector<RemovedParameter>& removedParameters();
/// "" unless `name` is a removed parameter; then the sentence saying so: "contrast_min_std was removed in
/// this version; it is now fixed at 0.01 (why)". setParameterChecked (params files, the nodelets' private
/// parameters; it adds "; the value given is ignored") and applyParameter (--set, the strict file loader: an
/// error) answer a removed name with it instead of "unknown parameter".
std::string removedParameterSentence(const std::string& name);

/// The names of the table close to `name` (a misspelling: one edit, or a name containing it), sorted.
std::vector<std::string> similarParameterNames(const std::string& name);
/// " (did you mean a b?)" with the similarParameterNames of `name` (only the preprocessor's and the
/// localizer's with `localizing_only`: what --set takes), or "" when there are none.
std::string didYouMean(const std::string& name, bool localizing_only = false);

/// Sets the field called `name` (a preprocessor or localizer parameter) from its text `value`. Returns
/// false with *error set for an unknown name or a value that does not parse (ranges are checked later by
/// validate()).
bool applyParameter(const std::string& name, const std::string& value, PreprocessingParams* preprocessing,
                    LocalizerParams* localizer, std::string* error);

/// Every name applyParameter() knows, sorted, for --help and error messages.
std::vector<std::string> parameterNames();
/// Those of PreprocessingParams (step 1: the preprocessor's, stored in the map) ...
std::vector<std::string> preprocessingParameterNames();
/// ... and those of LocalizerParams (steps 2-5: the localizer's).
std::vector<std::string> localizerParameterNames();

/// The private parameters a nodelet of `group` reads besides the table's: its ROS settings (the map path,
/// topics' queues and transports, rates), which the offline tools have no use for. The nodelets warn about
/// any other name under their namespace; a parameter file's section may hold these.
const std::set<std::string>& nodeletSettingNames(ParameterGroup group);

/// One "name: value" entry of a parameter file, the line it is on (for error messages) and the section it
/// is under ("" in a flat file).
struct ParameterEntry
{
  std::string name, value;
  int line = 0;
  std::string section;
};

/// Reads the entries of a flat YAML mapping ("name: value" per line, '#' comments, optional single
/// top-level section headers such as "localizer:" whose indented entries are read the same way) without
/// applying them, each with its section, so the launch files' params_file (sections preprocessor:,
/// map_recorder:, localizer:, route_follower:) can be given as it is. Returns false with *error naming the
/// file and line when the file cannot be read, a line is not "name: value", or YAML (which the launch files
/// read the file as) would read it otherwise: a header that is not one of those four sections, flow style
/// ("localizer: {max_step: 3}"), a tab or an indentation YAML refuses.
bool readParameterFile(const std::string& path, std::vector<ParameterEntry>* entries, std::string* error);

/// Applies the entries read from `path` in file order; those of the map_recorder: and route_follower:
/// sections are not the localizer's and are skipped. Returns false with *error naming the file and line
/// on the first unknown name, unparsable value, name given twice, or entry under the section of a nodelet
/// that does not read it (the launch files set it there, where it is ignored). Booleans: true/false,
/// yes/no, on/off (as YAML 1.1 and rosparam read them), 1/0.
bool applyParameterEntries(const std::string& path, const std::vector<ParameterEntry>& entries,
                           PreprocessingParams* preprocessing, LocalizerParams* localizer, std::string* error);

/// As applyParameterEntries, but one bad entry does not cost the others: an unknown name, a value that
/// does not parse, a name not among the choices or an entry under another nodelet's section is refused
/// (the parameter keeps its value), a number outside its working range is corrected
/// (setParameterChecked); each is a sentence in *warnings, naming the file, line and parameter. The
/// map_recorder: and route_follower: sections are checked the same way, as their nodelets read them, and
/// not applied; a nodelet's own setting in its section (nodeletSettingNames) is taken without a word.
/// Returns false with *error only for a name given twice in one section (which value was meant is unknown).
bool applyParameterEntriesChecked(const std::string& path, const std::vector<ParameterEntry>& entries,
                                  PreprocessingParams* preprocessing, LocalizerParams* localizer,
                                  std::vector<std::string>* warnings, std::string* error);

/// readParameterFile, then applyParameterEntries.
bool loadParameterFile(const std::string& path, PreprocessingParams* preprocessing, LocalizerParams* localizer,
                       std::string* error);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_PARAMETERS_H
