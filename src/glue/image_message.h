// What the core needs of an incoming sensor_msgs/Image, checked in one place for the preprocessor
// nodelet and the offline tools' bag reader.
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_IMAGE_MESSAGE_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_IMAGE_MESSAGE_H

#include <string>

#include <sensor_msgs/Image.h>

#include "along_route_localization/preprocessing.h"

namespace along_route_localization
{

/// What can be wrong with an image message, by kind (a log throttled per kind still says each kind).
enum class ImageProblem
{
  kNone,
  kEncoding,   ///< not one the core accepts
  kGeometry,   ///< a width, height or step its data does not hold (cv_bridge wraps without checking)
  kByteOrder,  ///< big-endian multi-byte pixels
};

/// kNone when the message can be wrapped as an image of a supported encoding (then *format is set),
/// else the kind of problem, with *sentence saying what is wrong with this message.
ImageProblem imageMessageProblem(const sensor_msgs::Image& msg, PixelFormat* format, std::string* sentence);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_IMAGE_MESSAGE_H
