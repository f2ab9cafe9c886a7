#include "along_route_localization/preprocessing.h"

#include "along_route_localization/parameters.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <sstream>

#include <opencv2/imgproc.hpp>

namespace along_route_localization
{

bool pixelFormatFromEncoding(const std::string& encoding, PixelFormat* format)
{
  static const std::map<std::string, PixelFormat> kFormats = {
    { "mono8", PixelFormat::kMono8 },   { "8UC1", PixelFormat::kMono8 },
    { "mono16", PixelFormat::kMono16 }, { "16UC1", PixelFormat::kMono16 },
    { "bgr8", PixelFormat::kBgr8 },     { "rgb8", PixelFormat::kRgb8 },
    { "bgra8", PixelFormat::kBgra8 },   { "rgba8", PixelFormat::kRgba8 },
    { "32FC1", PixelFormat::kMono32F },
  };
  const auto it = kFormats.find(encoding);
  if (it == kFormats.end())
    return false;
  *format = it->second;
  return true;
}

std::string supportedEncodings()
{
  return "mono8, 8UC1, mono16, 16UC1, bgr8, rgb8, bgra8, rgba8, 32FC1";
}

std::string toString(NormalizationMethod method)
{
  switch (method)
  {
    case NormalizationMethod::kNone:
      return "none";
    case NormalizationMethod::kPatch:
      return "patch";
    case NormalizationMethod::kDivisive:
      return "divisive";
  }
  return "unknown";
}

bool normalizationFromString(const std::string& name, NormalizationMethod* method)
{
  for (NormalizationMethod m : { NormalizationMethod::kNone, NormalizationMethod::kPatch, NormalizationMethod::kDivisive })
  {
    if (toString(m) == name)
    {
      *method = m;
      return true;
    }
  }
  return false;
}

int PreprocessingParams::skyRows() const
{
  return static_cast<int>(std::lround(sky_fraction * output_height));
}

std::string PreprocessingParams::validate() const
{
  // Each field's working range is the parameter table's; here the combinations.
  ParameterSet set;
  set.preprocessing = *this;
  const std::string out_of_range = checkRanges(ParameterGroup::kPreprocessor, set);
  if (!out_of_range.empty())
    return out_of_range;
  std::ostringstream error;
  if (!std::isfinite(min_patch_std + normalization_strength + output_gain + sky_fraction))
    error << "every parameter must be a finite number";
  else if (normalization == NormalizationMethod::kPatch &&
           (output_width % patch_size != 0 || output_height % patch_size != 0))
    error << "patch_size must divide output_width (" << output_width << ") and output_height (" << output_height
          << "), got " << patch_size;
  else if (filter_window % 2 == 0)
    error << "filter_window must be odd, got " << filter_window;
  return error.str();
}

std::vector<std::string> PreprocessingParams::correctCombinations()
{
  std::vector<std::string> corrections;
  if (filter_window % 2 == 0)
  {
    corrections.push_back("filter_window " + std::to_string(filter_window) + " is even; using " +
                          std::to_string(filter_window + 1));
    filter_window += 1;
  }
  if (normalization == NormalizationMethod::kPatch && output_width > 0 && output_height > 0 && patch_size > 0)
  {
    int common = output_width;  // greatest common divisor of the output size
    for (int other = output_height; other != 0;)
    {
      const int rest = common % other;
      common = other;
      other = rest;
    }
    if (common % patch_size != 0)
    {
      // The largest common divisor below it; none of at least 2 (patch_size's least): validate() refuses.
      int divisor = std::min(patch_size, common);
      while (common % divisor != 0)
        --divisor;
      if (divisor >= 2)
      {
        corrections.push_back("patch_size " + std::to_string(patch_size) + " does not divide the output size " +
                              std::to_string(output_width) + "x" + std::to_string(output_height) + "; using " +
                              std::to_string(divisor));
        patch_size = divisor;
      }
    }
  }
  return corrections;
}

std::string PreprocessingParams::serialize() const
{
  std::ostringstream out;
  out.precision(17);
  out << "output_width=" << output_width << ";output_height=" << output_height
      << ";normalization=" << toString(normalization) << ";patch_size=" << patch_size
      << ";min_patch_std=" << min_patch_std << ";filter_window=" << filter_window
      << ";normalization_strength=" << normalization_strength << ";output_gain=" << output_gain
      << ";sky_fraction=" << sky_fraction;
  return out.str();
}

bool PreprocessingParams::parse(const std::string& text, PreprocessingParams* params, std::string* error)
{
  std::map<std::string, std::string> fields;
  std::istringstream in(text);
  std::string item;
  while (std::getline(in, item, ';'))
  {
    if (item.empty())
      continue;
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0)
    {
      *error = "malformed field '" + item + "' (expected key=value)";
      return false;
    }
    fields[item.substr(0, eq)] = item.substr(eq + 1);
  }
  PreprocessingParams p;
  const auto number = [&](const char* key, double* value) {
    const auto it = fields.find(key);
    if (it == fields.end())
    {
      *error = std::string("missing field '") + key + "'";
      return false;
    }
    try
    {
      size_t used = 0;
      *value = std::stod(it->second, &used);
      if (used != it->second.size())
        throw std::invalid_argument(it->second);
    }
    catch (const std::exception&)
    {
      *error = std::string("field '") + key + "' is not a number: '" + it->second + "'";
      return false;
    }
    return true;
  };
  double width, height, patch, min_std, window, strength, gain, sky;
  if (!number("output_width", &width) || !number("output_height", &height) || !number("patch_size", &patch) ||
      !number("min_patch_std", &min_std) || !number("filter_window", &window) ||
      !number("normalization_strength", &strength) || !number("output_gain", &gain) ||
      !number("sky_fraction", &sky))
    return false;
  const auto method = fields.find("normalization");
  if (method == fields.end() || !normalizationFromString(method->second, &p.normalization))
  {
    *error = "missing or unknown field 'normalization'";
    return false;
  }
  p.output_width = static_cast<int>(width);
  p.output_height = static_cast<int>(height);
  p.patch_size = static_cast<int>(patch);
  p.min_patch_std = min_std;
  p.filter_window = static_cast<int>(window);
  p.normalization_strength = strength;
  p.output_gain = gain;
  p.sky_fraction = sky;
  const std::string invalid = p.validate();
  if (!invalid.empty())
  {
    *error = invalid;
    return false;
  }
  *params = p;
  return true;
}

PreprocessingParams PreprocessingParams::canonical() const
{
  const PreprocessingParams defaults;
  PreprocessingParams c = *this;
  if (normalization != NormalizationMethod::kPatch)
  {
    c.patch_size = defaults.patch_size;
    c.min_patch_std = defaults.min_patch_std;
  }
  if (normalization != NormalizationMethod::kDivisive)
  {
    c.filter_window = defaults.filter_window;
    c.normalization_strength = defaults.normalization_strength;
  }
  if (normalization == NormalizationMethod::kNone)
    c.output_gain = defaults.output_gain;
  return c;
}

bool PreprocessingParams::operator==(const PreprocessingParams& o) const
{
  return canonical().serialize() == o.canonical().serialize();
}

void toGray(const cv::Mat& input, PixelFormat format, cv::Mat& gray)
{
  if (input.empty())
    throw PreprocessingError("empty image (0 x 0)");
  static const std::map<PixelFormat, int> kTypes = {
    { PixelFormat::kMono8, CV_8UC1 },  { PixelFormat::kMono16, CV_16UC1 }, { PixelFormat::kBgr8, CV_8UC3 },
    { PixelFormat::kRgb8, CV_8UC3 },   { PixelFormat::kBgra8, CV_8UC4 },   { PixelFormat::kRgba8, CV_8UC4 },
    { PixelFormat::kMono32F, CV_32FC1 },
  };
  if (input.type() != kTypes.at(format))
    throw PreprocessingError("image data of type " + cv::typeToString(input.type()) +
                             " does not match its encoding (expected " + cv::typeToString(kTypes.at(format)) + ")");
  switch (format)
  {
    case PixelFormat::kMono8:
      gray = input;  // no copy: the caller only reads it
      break;
    case PixelFormat::kMono16:
      input.convertTo(gray, CV_8U, 1.0 / 257.0);
      break;
    case PixelFormat::kBgr8:
      cv::cvtColor(input, gray, cv::COLOR_BGR2GRAY);
      break;
    case PixelFormat::kRgb8:
      cv::cvtColor(input, gray, cv::COLOR_RGB2GRAY);
      break;
    case PixelFormat::kBgra8:
      cv::cvtColor(input, gray, cv::COLOR_BGRA2GRAY);
      break;
    case PixelFormat::kRgba8:
      cv::cvtColor(input, gray, cv::COLOR_RGBA2GRAY);
      break;
    case PixelFormat::kMono32F:
      if (!cv::checkRange(input, true))
        throw PreprocessingError("float image contains NaN or infinite values");
      input.convertTo(gray, CV_8U, 255.0);
      break;
  }
}

bool floatOutsideUnitRange(const cv::Mat& input, std::string* sentence)
{
  if (input.type() != CV_32FC1 || input.empty())
    return false;
  float low = std::numeric_limits<float>::infinity(), high = -low;
  for (int y = 0; y < input.rows; ++y)
  {
    const float* row = input.ptr<float>(y);
    for (int x = 0; x < input.cols; ++x)
      if (std::isfinite(row[x]))
      {
        low = std::min(low, row[x]);
        high = std::max(high, row[x]);
      }
  }
  if (!(low < 0.0f || high > 1.0f))
    return false;
  if (sentence)
  {
    char text[160];
    std::snprintf(text, sizeof(text), "32FC1 values from %g to %g, outside the [0, 1] read as intensity: clipped",
                  static_cast<double>(low), static_cast<double>(high));
    *sentence = text;
  }
  return true;
}

bool inputSmallerThanOutput(int width, int height, const PreprocessingParams& params, std::string* sentence)
{
  if (width <= 0 || height <= 0 || (width >= params.output_width && height >= params.output_height))
    return false;
  if (sentence)
  {
    char text[200];
    std::snprintf(text, sizeof(text),
                  "smaller than the %dx%d output: enlarged, it holds less detail than the output has room for "
                  "(a camera mode of at least %dx%d px, or smaller output_width / output_height)",
                  params.output_width, params.output_height, params.output_width, params.output_height);
    *sentence = text;
  }
  return true;
}

void patchNormalize(cv::Mat& image, int patch_size, double min_std, double gain)
{
  CV_Assert(image.type() == CV_8UC1 && image.rows % patch_size == 0 && image.cols % patch_size == 0);
  const double area = static_cast<double>(patch_size) * patch_size;
  for (int py = 0; py < image.rows; py += patch_size)
  {
    for (int px = 0; px < image.cols; px += patch_size)
    {
      double sum = 0.0, sum_sq = 0.0;
      for (int y = py; y < py + patch_size; ++y)
      {
        const uint8_t* row = image.ptr<uint8_t>(y);
        for (int x = px; x < px + patch_size; ++x)
        {
          sum += row[x];
          sum_sq += static_cast<double>(row[x]) * row[x];
        }
      }
      const double mean = sum / area;
      const double std = std::sqrt(std::max(0.0, sum_sq / area - mean * mean));
      const bool flat = std < min_std || std <= 0.0;
      const double scale = flat ? 0.0 : gain / std;
      for (int y = py; y < py + patch_size; ++y)
      {
        uint8_t* row = image.ptr<uint8_t>(y);
        for (int x = px; x < px + patch_size; ++x)
          row[x] = cv::saturate_cast<uint8_t>(128.0 + scale * (row[x] - mean));
      }
    }
  }
}

void divisiveNormalize(const cv::Mat& input, cv::Mat& output, int filter_window, double strength, double gain)
{
  CV_Assert(input.type() == CV_8UC1 && input.data != output.data);
  cv::Mat value, mean, mean_sq;
  input.convertTo(value, CV_32F);
  const cv::Size window(filter_window, filter_window);
  cv::GaussianBlur(value, mean, window, 0.0, 0.0, cv::BORDER_REFLECT_101);
  cv::GaussianBlur(value.mul(value), mean_sq, window, 0.0, 0.0, cv::BORDER_REFLECT_101);
  output.create(input.size(), CV_8UC1);
  for (int y = 0; y < input.rows; ++y)
  {
    const float* v = value.ptr<float>(y);
    const float* mu = mean.ptr<float>(y);
    const float* mu2 = mean_sq.ptr<float>(y);
    uint8_t* out = output.ptr<uint8_t>(y);
    for (int x = 0; x < input.cols; ++x)
    {
      const double sigma = std::sqrt(std::max(0.0, static_cast<double>(mu2[x]) - static_cast<double>(mu[x]) * mu[x]));
      const double normalized = (v[x] - mu[x]) / (1.0 + strength * sigma);  // eq. 3
      out[x] = cv::saturate_cast<uint8_t>(128.0 + gain * strength * normalized);
    }
  }
}

Preprocessor::Preprocessor(const PreprocessingParams& params)
{
  setParams(params);
}

void Preprocessor::setParams(const PreprocessingParams& params)
{
  const std::string invalid = params.validate();
  if (!invalid.empty())
    throw PreprocessingError("invalid preprocessing parameters: " + invalid);
  params_ = params;
}

void Preprocessor::process(const cv::Mat& input, PixelFormat format, cv::Mat& output)
{
  // gray_ is scratch for conversions and must only ever hold a buffer of its own: a mono8 input is read
  // in place (toGray makes `gray` a header on it), and such a header kept past this call pointed into
  // the caller's buffer (a message, freed after the callback), so the next colour frame of the same
  // size was converted into freed memory.
  cv::Mat gray = gray_;
  toGray(input, format, gray);
  if (format != PixelFormat::kMono8)
    gray_ = gray;  // keeps the buffer toGray (re)allocated for the next frame
  const cv::Size size(params_.output_width, params_.output_height);
  if (output.size() != size || output.type() != CV_8UC1)
    output.create(size, CV_8UC1);
  // INTER_AREA averages all source pixels of a cell, the downsampling SeqSLAM relies on.
  cv::Mat& target = params_.normalization == NormalizationMethod::kDivisive ? small_ : output;
  cv::resize(gray, target, size, 0.0, 0.0, cv::INTER_AREA);
  switch (params_.normalization)
  {
    case NormalizationMethod::kNone:
      break;
    case NormalizationMethod::kPatch:
      patchNormalize(output, params_.patch_size, params_.min_patch_std, params_.output_gain);
      break;
    case NormalizationMethod::kDivisive:
      divisiveNormalize(small_, output, params_.filter_window, params_.normalization_strength, params_.output_gain);
      break;
  }
  const int sky_rows = params_.skyRows();
  if (sky_rows > 0)
    output.rowRange(0, sky_rows).setTo(0);
}

}  // namespace along_route_localization
