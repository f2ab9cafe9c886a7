#include "glue/image_message.h"

#include <sstream>

#include <sensor_msgs/image_encodings.h>

namespace along_route_localization
{

ImageProblem imageMessageProblem(const sensor_msgs::Image& msg, PixelFormat* format, std::string* sentence)
{
  std::ostringstream problem;
  if (!pixelFormatFromEncoding(msg.encoding, format))
  {
    problem << msg.width << "x" << msg.height << " image with unsupported encoding '" << msg.encoding
            << "'; accepted encodings: " << supportedEncodings();
    *sentence = problem.str();
    return ImageProblem::kEncoding;
  }
  const int channels = sensor_msgs::image_encodings::numChannels(msg.encoding);
  const int bytes_per_pixel = channels * sensor_msgs::image_encodings::bitDepth(msg.encoding) / 8;
  if (msg.width == 0 || msg.height == 0 || msg.step < msg.width * static_cast<uint64_t>(bytes_per_pixel) ||
      msg.data.size() < static_cast<uint64_t>(msg.step) * msg.height)
  {
    problem << "malformed '" << msg.encoding << "' image: " << msg.width << "x" << msg.height << " px, step "
            << msg.step << ", " << msg.data.size() << " bytes of data (need width, height > 0, step >= width * "
            << bytes_per_pixel << " and step * height bytes)";
    *sentence = problem.str();
    return ImageProblem::kGeometry;
  }
  if (msg.is_bigendian && bytes_per_pixel / channels > 1)
  {
    problem << "big-endian '" << msg.encoding << "' image: only little-endian multi-byte pixels are accepted";
    *sentence = problem.str();
    return ImageProblem::kByteOrder;
  }
  sentence->clear();
  return ImageProblem::kNone;
}

}  // namespace along_route_localization
