// dynamic_reconfigure configs (cfg/*.cfg) -> core parameters. One place, so the nodelets and the test
// that holds the .cfg defaults equal to the core defaults use the same mapping.
#ifndef ALONG_ROUTE_LOCALIZATION_ROS_RECONFIGURE_H
#define ALONG_ROUTE_LOCALIZATION_ROS_RECONFIGURE_H

#include <string>

#include "along_route_localization/LocalizerConfig.h"
#include "along_route_localization/PreprocessorConfig.h"
#include "along_route_localization/RouteFollowerConfig.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_follower.h"

namespace along_route_localization
{

/// Every field of PreprocessingParams comes from the config. dynamic_reconfigure does not hold a string
/// to its enum: an unknown normalization name becomes patch and, when `problem` is given, is named there.
PreprocessingParams toParams(const PreprocessorConfig& config, std::string* problem = nullptr);

/// The fields Localizer.cfg exposes come from the config, the others from `base` (static parameters).
/// horizontal_fov_deg becomes horizontal_fov_rad; an unknown method name becomes dtw and, when `problem`
/// is given, is named there.
LocalizerParams toParams(const LocalizerConfig& config, LocalizerParams base, std::string* problem = nullptr);

/// Every field of RouteFollowerParams comes from the config (max_homing_turn_rate -> max_homing_turn_rps,
/// homing_time_constant -> homing_time_constant_s, watchdog_timeout -> watchdog_timeout_s).
RouteFollowerParams toParams(const RouteFollowerConfig& config);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROS_RECONFIGURE_H
