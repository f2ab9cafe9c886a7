// Parameters by name: the one table mapping the names users type (params.yaml, command line) to the
// fields of PreprocessingParams and LocalizerParams. The dynamic_reconfigure .cfg files use the same names.
#ifndef ALONG_ROUTE_LOCALIZATION_PARAMETERS_H
#define ALONG_ROUTE_LOCALIZATION_PARAMETERS_H

#include <string>
#include <vector>

#include "along_route_localization/localizer.h"
#include "along_route_localization/preprocessing.h"

namespace along_route_localization
{

/// Sets the field called `name` from its text `value`. Returns false with *error set for an unknown
/// name or a value that does not parse (ranges are checked later by validate()).
bool applyParameter(const std::string& name, const std::string& value, PreprocessingParams* preprocessing,
                    LocalizerParams* localizer, std::string* error);

/// Every name applyParameter() knows, sorted, for --help and error messages.
std::vector<std::string> parameterNames();
/// Those of PreprocessingParams (step 1: the preprocessor's, stored in the map) ...
std::vector<std::string> preprocessingParameterNames();
/// ... and those of LocalizerParams (steps 2-5: the localizer's).
std::vector<std::string> localizerParameterNames();

/// One "name: value" entry of a parameter file and the line it is on (for error messages).
struct ParameterEntry
{
  std::string name, value;
  int line = 0;
};

/// Reads the entries of a flat YAML mapping ("name: value" per line, '#' comments, optional single
/// top-level section headers such as "localizer:" whose indented entries are read the same way) without
/// applying them. The entries of a "map_recorder:" section are skipped, so the launch files' params_file
/// (sections preprocessor:, map_recorder:, localizer:) can be given as it is. Returns false with *error
/// naming the file and line when the file cannot be read or a line is not "name: value".
bool readParameterFile(const std::string& path, std::vector<ParameterEntry>* entries, std::string* error);

/// Applies the entries read from `path` in file order. Returns false with *error naming the file and line
/// on the first unknown name, unparsable value, or name given twice. Booleans: true/false, yes/no,
/// on/off (as YAML 1.1 and rosparam read them), 1/0.
bool applyParameterEntries(const std::string& path, const std::vector<ParameterEntry>& entries,
                           PreprocessingParams* preprocessing, LocalizerParams* localizer, std::string* error);

/// readParameterFile, then applyParameterEntries.
bool loadParameterFile(const std::string& path, PreprocessingParams* preprocessing, LocalizerParams* localizer,
                       std::string* error);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_PARAMETERS_H
