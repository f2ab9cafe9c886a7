// Frames from disk for the offline tools: image folders, bags with an image topic, recorder map files.
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_FRAME_SOURCE_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_FRAME_SOURCE_H

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"

namespace along_route_localization
{

/// Image files of a folder in file-name order (png, jpg, jpeg, bmp, pgm, ppm, tif, tiff).
std::vector<std::string> listImageFiles(const std::string& folder);

/// Called as frames are read: (frames read so far, frames in all), in increasing order, from one thread at
/// a time (the folder reader's workers take turns).
using LoadProgress = std::function<void(size_t done, size_t total)>;

/// Preprocessed frames (mono8) of a folder of images or of an image topic of a bag (`topic` empty:
/// the bag's only sensor_msgs/Image topic). Throws std::runtime_error with a clear message for a missing
/// path, an unreadable image, an unsupported encoding, or a bag with no/several image topics.
/// stamps_ns (optional): each frame's header stamp in ns; 0 (unknown) for the images of a folder.
std::vector<cv::Mat> loadPreprocessedFrames(const std::string& path, const std::string& topic,
                                            const PreprocessingParams& params,
                                            std::vector<int64_t>* stamps_ns = nullptr,
                                            const LoadProgress& progress = LoadProgress());

/// A route map from a recorder map file (its stored parameters replace *params), or from a folder / image
/// bag (every image a keyframe, preprocessed with *params; stamps from the bag, or the file index in ns).
std::shared_ptr<RouteMap> loadMapFromPath(const std::string& path, const std::string& topic,
                                          PreprocessingParams* params, const LoadProgress& progress = LoadProgress());

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_FRAME_SOURCE_H
