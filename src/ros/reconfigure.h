// dynamic_reconfigure configs (cfg/*.cfg) -> core parameters. One place, so the nodelets and the test
// that holds the .cfg defaults equal to the core defaults use the same mapping.
#ifndef ALONG_ROUTE_LOCALIZATION_ROS_RECONFIGURE_H
#define ALONG_ROUTE_LOCALIZATION_ROS_RECONFIGURE_H

#include "along_route_localization/LocalizerConfig.h"
#include "along_route_localization/PreprocessorConfig.h"
#include "along_route_localization/localizer.h"
#include "along_route_localization/preprocessing.h"

namespace along_route_localization
{

/// Every field of PreprocessingParams comes from the config (an unknown normalization name: patch).
PreprocessingParams toParams(const PreprocessorConfig& config);

/// The fields Localizer.cfg exposes come from the config, the others from `base` (static parameters).
/// horizontal_fov_deg becomes horizontal_fov_rad; an unknown method name becomes dtw.
LocalizerParams toParams(const LocalizerConfig& config, LocalizerParams base);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROS_RECONFIGURE_H
