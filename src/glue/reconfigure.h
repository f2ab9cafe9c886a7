// dynamic_reconfigure configs (cfg/*.cfg) -> core parameters. One place, so the nodelets and the test
// that holds the .cfg defaults equal to the core defaults use the same mapping.
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_RECONFIGURE_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_RECONFIGURE_H

#include <string>
#include <vector>

#include <dynamic_reconfigure/Config.h>

#include "along_route_localization/LocalizerConfig.h"
#include "along_route_localization/PreprocessorConfig.h"
#include "along_route_localization/RouteFollowerConfig.h"
#include "along_route_localization/MapRecorderConfig.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/parameters.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_follower.h"

namespace along_route_localization
{

/// Every field of PreprocessingParams comes from the config, through the parameter table (each .cfg name is
/// a table name). dynamic_reconfigure does not hold a string to its enum: an unknown normalization name
/// leaves the default and, when `problem` is given, is named there.
PreprocessingParams toParams(const PreprocessorConfig& config, std::string* problem = nullptr);

/// The fields Localizer.cfg exposes come from the config (through the parameter table: horizontal_fov_deg
/// sets horizontal_fov_rad), the others from `base` (static parameters); an unknown method name leaves
/// base's and, when `problem` is given, is named there.
LocalizerParams toParams(const LocalizerConfig& config, LocalizerParams base, std::string* problem = nullptr);

/// Every field of RouteFollowerParams comes from the config, through the parameter table
/// (max_homing_turn_rate sets max_homing_turn_rps, homing_time_constant homing_time_constant_s,
/// watchdog_timeout watchdog_timeout_s).
RouteFollowerParams toParams(const RouteFollowerConfig& config);
/// The map recorder's keyframe policy from its config.
KeyframePolicy toPolicy(const MapRecorderConfig& config);

/// What a config callback makes of a new config: the values not used as given (for WARN), each change
/// from the config in use ("ring_buffer_rows 30 -> 10", for INFO), or why the whole config was refused.
struct ConfigReview
{
  std::vector<std::string> corrections;
  std::vector<std::string> changes;
  std::string rejected;  ///< not empty: the previous config is kept
};

/// The entry called `name` of one of a dynamic_reconfigure message's lists (ints, doubles, strs, bools),
/// or nullptr.
template <class Value>
const Value* findByName(const std::vector<Value>& values, const std::string& name)
{
  for (const Value& value : values)
    if (value.name == name)
      return &value;
  return nullptr;
}

/// The sentences of one dynamic_reconfigure message (ints, doubles, strs, bools), by name.
std::vector<std::string> correctToTable(dynamic_reconfigure::Config* msg, const dynamic_reconfigure::Config& previous);
std::vector<std::string> configChanges(const dynamic_reconfigure::Config& before, const dynamic_reconfigure::Config& after);

/// Each of config's parameters checked against the parameter table (parameters.h): a number outside its
/// working range is set to the nearest end of it, a name that is not one of the choices goes back to its
/// value in `previous`. One sentence per value not used as given. The .cfg files declare no range, so that
/// dynamic_reconfigure, which clamps to the .cfg range without a word, hands the callback the value asked for.
template <class Config>
std::vector<std::string> correctToTable(Config& config, const Config& previous)
{
  dynamic_reconfigure::Config msg, before;
  config.__toMessage__(msg);
  previous.__toMessage__(before);
  const std::vector<std::string> corrections = correctToTable(&msg, before);
  config.__fromMessage__(msg);
  return corrections;
}

/// The end of a config callback, after correctToTable and the nodelet's own corrections (`corrections`):
/// `invalid` (validate() of the parameters made from config) not empty refuses the whole config and sets
/// it back to `last_valid`; otherwise the changes from `last_valid` are listed and config becomes it.
template <class Config>
ConfigReview reviewConfig(Config& config, Config& last_valid, std::vector<std::string> corrections,
                          const std::string& invalid)
{
  ConfigReview review;
  review.corrections = std::move(corrections);
  if (!invalid.empty())
  {
    review.rejected = invalid;
    config = last_valid;
    return review;
  }
  dynamic_reconfigure::Config before, after;
  last_valid.__toMessage__(before);
  config.__toMessage__(after);
  review.changes = configChanges(before, after);
  last_valid = config;
  return review;
}

/// Logs a review under `logger` (the nodelet's name, as NODELET_* do): each correction at WARN, a refusal
/// at ERROR, each change at INFO. `what`: "localizer parameters", for the refusal's sentence.
void logConfigReview(const ConfigReview& review, const std::string& logger, const std::string& what);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_RECONFIGURE_H
