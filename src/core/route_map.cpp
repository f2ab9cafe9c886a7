#include "along_route_localization/route_map.h"

#include "along_route_localization/image_difference.h"

namespace along_route_localization
{

RouteMap::RouteMap(const PreprocessingParams& params) : params_(params)
{
  const std::string invalid = params.validate();
  if (!invalid.empty())
    throw MapError("invalid preprocessing parameters for a map: " + invalid);
}

void RouteMap::addKeyframe(const cv::Mat& preprocessed, int64_t stamp_ns)
{
  if (preprocessed.type() != CV_8UC1 || preprocessed.cols != width() || preprocessed.rows != height())
    throw MapError("keyframe must be mono8 " + std::to_string(width()) + "x" + std::to_string(height()) + ", got " +
                   cv::typeToString(preprocessed.type()) + " " + std::to_string(preprocessed.cols) + "x" +
                   std::to_string(preprocessed.rows));
  const size_t offset = data_.size();
  data_.resize(offset + keyframeBytes());
  for (int y = 0; y < height(); ++y)
    std::copy_n(preprocessed.ptr<uint8_t>(y), width(), data_.data() + offset + static_cast<size_t>(y) * width());
  stamps_ns_.push_back(stamp_ns);
  energy_.push_back(textureEnergy(data_.data() + offset, width(), height(), params_.skyRows()));
}

void RouteMap::reserve(size_t keyframes)
{
  data_.reserve(keyframes * keyframeBytes());
  stamps_ns_.reserve(keyframes);
  energy_.reserve(keyframes);
}

cv::Mat RouteMap::keyframeMat(size_t index) const
{
  return cv::Mat(height(), width(), CV_8UC1, const_cast<uint8_t*>(keyframe(index)));
}

}  // namespace along_route_localization
