// libFuzzer target: the image input path, camera frame -> Preprocessor::process -> Localizer::process.
// Built and run by scripts/run_sanitizers.sh with AddressSanitizer and UndefinedBehaviorSanitizer.
//
// Input: an 8-byte header, then pixel bytes (missing bytes are zero, extra bytes ignored).
//   byte 0  bits 0-2 pixel format (index into kFormats); bit 3: the cv::Mat type comes from bits 4-6
//           (index into kTypes) instead of matching the format -- an image whose data lies about its encoding
//   byte 1  input width  = 1 + byte % 96 px
//   byte 2  input height = 1 + byte % 64 px
//   byte 3  bits 0-1 normalization; bits 2-3 output size (kOutputSizes); bit 4 sky_fraction 0.25;
//           bits 5-6 filter_window (kFilterWindows); bit 7 the input is a view into a larger image
//           (rows not contiguous)
//   byte 4  bit 0 census cost; bit 1 SeqSLAM; bit 2 subpixel; bit 3 energy-normalized cost; bit 4 parallel;
//           bits 5-7 max_shift_px (kMaxShifts, some invalid for small images)
//   byte 5  keyframes in the map = 1 + byte % 16
//   byte 6  frames fed = 1 + byte % 8; ring_buffer_rows = 3 + (byte >> 3) % 8 (its least)
//   byte 7  min_init_frames = 1 + byte % 3 (at most ring_buffer_rows); bit 2 stationary detection; bit 3 texture threshold
// Every input must give a localization, a PreprocessingError or std::invalid_argument (invalid
// parameters): anything else -- a crash, a sanitizer report, a cv::Exception -- is a bug.
#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <stdexcept>

#include <opencv2/core.hpp>

#include "along_route_localization/localizer.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"

namespace arl = along_route_localization;

namespace
{

const arl::PixelFormat kFormats[] = { arl::PixelFormat::kMono8, arl::PixelFormat::kMono16, arl::PixelFormat::kBgr8,
                                      arl::PixelFormat::kRgb8,  arl::PixelFormat::kBgra8,  arl::PixelFormat::kRgba8,
                                      arl::PixelFormat::kMono32F };
const int kFormatTypes[] = { CV_8UC1, CV_16UC1, CV_8UC3, CV_8UC3, CV_8UC4, CV_8UC4, CV_32FC1 };
const int kTypes[] = { CV_8UC1, CV_16UC1, CV_8UC3, CV_8UC4, CV_32FC1, CV_8UC2, CV_64FC1, CV_16SC3 };
const cv::Size kOutputSizes[] = { { 8, 4 }, { 16, 8 }, { 32, 8 }, { 64, 32 } };
const int kFilterWindows[] = { 3, 5, 7, 63 };
const int kMaxShifts[] = { 0, 1, 2, 4, 7, 15, 31, 127 };

std::shared_ptr<arl::RouteMap> tinyMap(const arl::PreprocessingParams& params, int keyframes)
{
  auto map = std::make_shared<arl::RouteMap>(params);
  cv::RNG rng(1234);
  cv::Mat keyframe(params.output_height, params.output_width, CV_8UC1);
  for (int k = 0; k < keyframes; ++k)
  {
    rng.fill(keyframe, cv::RNG::UNIFORM, 0, 256);
    if (k % 5 == 4)
      keyframe.setTo(128);  // a featureless keyframe now and then
    map->addKeyframe(keyframe, 1000000000LL * k);
  }
  return map;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
  if (size < 8)
    return 0;
  const uint8_t* header = data;
  const uint8_t* pixels = data + 8;
  const size_t pixel_bytes = size - 8;

  const int format_index = header[0] & 7;
  if (format_index >= 7)
    return 0;
  const arl::PixelFormat format = kFormats[format_index];
  const int type = (header[0] & 8) ? kTypes[(header[0] >> 4) & 7] : kFormatTypes[format_index];
  const int width = 1 + header[1] % 96;
  const int height = 1 + header[2] % 64;
  const bool view = (header[3] & 0x80) != 0;

  // The frame: pixel bytes copied in row by row, the rest zero.
  cv::Mat storage(height + (view ? 2 : 0), width + (view ? 3 : 0), type, cv::Scalar::all(0));
  cv::Mat input = view ? storage(cv::Rect(1, 1, width, height)) : storage;
  const size_t row_bytes = static_cast<size_t>(width) * input.elemSize();
  size_t used = 0;
  for (int y = 0; y < height && used < pixel_bytes; ++y)
  {
    const size_t count = std::min(row_bytes, pixel_bytes - used);
    std::memcpy(input.ptr(y), pixels + used, count);
    used += count;
  }

  arl::PreprocessingParams preprocessing;
  preprocessing.normalization = static_cast<arl::NormalizationMethod>((header[3] & 3) % 3);
  preprocessing.output_width = kOutputSizes[(header[3] >> 2) & 3].width;
  preprocessing.output_height = kOutputSizes[(header[3] >> 2) & 3].height;
  preprocessing.patch_size = 4;
  preprocessing.sky_fraction = (header[3] & 0x10) ? 0.25 : 0.0;
  preprocessing.filter_window = kFilterWindows[(header[3] >> 5) & 3];

  arl::LocalizerParams params;
  params.cost_function = (header[4] & 1) ? arl::CostFunction::kCensus : arl::CostFunction::kSad;
  params.method = (header[4] & 2) ? arl::SequenceMethod::kSeqSlam : arl::SequenceMethod::kOnlineDtw;
  params.subpixel_shift = (header[4] & 4) != 0;
  params.energy_normalized_cost = (header[4] & 8) != 0;
  params.parallel = (header[4] & 16) != 0;
  params.max_shift_px = kMaxShifts[(header[4] >> 5) & 7];
  const int keyframes = 1 + header[5] % 16;
  const int frames = 1 + header[6] % 8;
  params.ring_buffer_rows = 3 + (header[6] >> 3) % 8;
  params.min_init_frames = 1 + header[7] % 3;
  params.stationary_ratio = (header[7] & 4) ? 0.2f : 0.0f;
  params.min_texture_ratio = (header[7] & 8) ? 0.4f : 0.0f;
  params.search_radius = 3;
  params.lost_after_frames = 2;
  params.seqslam.sequence_length = 3;

  try
  {
    arl::Preprocessor preprocessor(preprocessing);
    cv::Mat preprocessed;
    preprocessor.process(input, format, preprocessed);
    if (preprocessed.type() != CV_8UC1 || preprocessed.cols != preprocessing.output_width ||
        preprocessed.rows != preprocessing.output_height)
      __builtin_trap();  // process() promises an image of the output size

    const std::shared_ptr<arl::RouteMap> map = tinyMap(preprocessing, keyframes);
    arl::Localizer localizer(map, params);
    for (int i = 0; i < frames; ++i)
    {
      // Alternate the fuzzed frame with map keyframes, so that tracking, stops and losses all happen.
      const cv::Mat& query = (i % 2 == 0) ? preprocessed : map->keyframeMat(static_cast<size_t>(i) % map->size());
      const arl::LocalizationResult result = localizer.process(query);
      if (!(result.confidence >= 0.0 && result.confidence <= 1.0) ||
          result.keyframe >= static_cast<int>(map->size()) || result.keyframe < -1)
        __builtin_trap();  // documented ranges of LocalizationResult
    }
    localizer.renderDebugImage(0, static_cast<int>(map->size()), 1);
  }
  catch (const std::invalid_argument&)  // PreprocessingError is one, and so are invalid parameters
  {
  }
  return 0;
}
