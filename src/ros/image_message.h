// What the core needs of an incoming sensor_msgs/Image, checked in one place for the preprocessor
// nodelet and the offline tools' bag reader.
#ifndef ALONG_ROUTE_LOCALIZATION_ROS_IMAGE_MESSAGE_H
#define ALONG_ROUTE_LOCALIZATION_ROS_IMAGE_MESSAGE_H

#include <string>

#include <sensor_msgs/Image.h>

#include "along_route_localization/preprocessing.h"

namespace along_route_localization
{

/// "" when the message can be wrapped as an image of a supported encoding (then *format is set),
/// else a sentence saying what is wrong: an unsupported encoding, a geometry its data does not hold
/// (cv_bridge wraps the buffer without checking it), or big-endian multi-byte pixels.
std::string imageMessageProblem(const sensor_msgs::Image& msg, PixelFormat* format);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROS_IMAGE_MESSAGE_H
