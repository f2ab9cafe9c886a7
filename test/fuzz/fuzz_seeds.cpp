// Writes the seed corpora of the fuzz targets (run by scripts/run_sanitizers.sh, nothing binary is
// committed):
//   fuzz_seeds MAP_DIR IMAGE_DIR
// MAP_DIR gets small valid maps written by the package's own writeMap (fuzz_map_loader), IMAGE_DIR
// valid frames of every pixel format in the input layout of fuzz_image_input.cpp.
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"
#include "glue/map_io.h"

namespace arl = along_route_localization;

namespace
{

void writeMapSeed(const std::string& path, const arl::PreprocessingParams& params, int keyframes, uint64_t seed)
{
  arl::RouteMap map(params);
  cv::RNG rng(seed);
  cv::Mat keyframe(params.output_height, params.output_width, CV_8UC1);
  for (int k = 0; k < keyframes; ++k)
  {
    rng.fill(keyframe, cv::RNG::UNIFORM, 0, 256);
    map.addKeyframe(keyframe, 1000000000LL * (k + 1) + 7);
  }
  arl::writeMap(path, map);
}

void writeImageSeed(const std::string& path, const std::vector<uint8_t>& header, int width, int height,
                    int bytes_per_pixel, uint64_t seed)
{
  std::vector<uint8_t> bytes(header);
  cv::RNG rng(seed);
  for (int i = 0; i < width * height * bytes_per_pixel; ++i)
    bytes.push_back(static_cast<uint8_t>(rng.uniform(0, 256)));
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace

int main(int argc, char** argv)
{
  if (argc != 3)
  {
    std::fprintf(stderr, "usage: fuzz_seeds MAP_DIR IMAGE_DIR\n");
    return 2;
  }
  const std::string map_dir = argv[1], image_dir = argv[2];
  try
  {
    arl::PreprocessingParams tiny;
    tiny.output_width = 8;
    tiny.output_height = 4;
    tiny.normalization = arl::NormalizationMethod::kNone;
    writeMapSeed(map_dir + "/tiny_none.bag", tiny, 2, 1);
    arl::PreprocessingParams small;
    small.output_width = 16;
    small.output_height = 8;
    small.patch_size = 4;
    small.sky_fraction = 0.25;
    writeMapSeed(map_dir + "/small_patch.bag", small, 3, 2);
    arl::PreprocessingParams divisive;
    divisive.output_width = 32;
    divisive.output_height = 8;
    divisive.normalization = arl::NormalizationMethod::kDivisive;
    writeMapSeed(map_dir + "/divisive.bag", divisive, 2, 3);
    writeMapSeed(map_dir + "/default.bag", arl::PreprocessingParams(), 1, 4);
  }
  catch (const arl::MapError& e)
  {
    std::fprintf(stderr, "fuzz_seeds: %s\n", e.what());
    return 1;
  }

  // Header bytes as fuzz_image_input.cpp reads them: format, width - 1, height - 1, preprocessing,
  // localizer, keyframes - 1, frames - 1 (+ rows), min_init_frames - 1 (+ flags).
  const int bytes_per_pixel[] = { 1, 2, 3, 3, 4, 4, 4 };
  for (int format = 0; format < 7; ++format)
  {
    const int width = 24 + 8 * format, height = 12 + 2 * format;
    const std::vector<uint8_t> header = { static_cast<uint8_t>(format), static_cast<uint8_t>(width - 1),
                                          static_cast<uint8_t>(height - 1), static_cast<uint8_t>(format % 3 | 0x04),
                                          static_cast<uint8_t>(format << 1 | 0x4c), 9, 0x1b, 0x0d };
    if (format == 6)  // 32FC1: random bytes are mostly huge or NaN floats; write values in [0, 1]
    {
      std::vector<uint8_t> bytes(header);
      cv::RNG rng(6);
      for (int i = 0; i < width * height; ++i)
      {
        const float value = static_cast<float>(rng.uniform(0.0, 1.0));
        const uint8_t* raw = reinterpret_cast<const uint8_t*>(&value);
        bytes.insert(bytes.end(), raw, raw + 4);
      }
      std::ofstream out(image_dir + "/format6.bin", std::ios::binary | std::ios::trunc);
      out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
      continue;
    }
    writeImageSeed(image_dir + "/format" + std::to_string(format) + ".bin", header, width, height,
                   bytes_per_pixel[format], 100 + format);
  }
  // A 64 x 32 mono8 frame with the default output size, and a view into a larger image.
  writeImageSeed(image_dir + "/default_size.bin", { 0, 63, 31, 0x0d, 0x84, 15, 0x3f, 0x0f }, 64, 32, 1, 200);
  writeImageSeed(image_dir + "/view.bin", { 2, 40, 20, 0x82, 0x45, 7, 0x12, 0x01 }, 41, 21, 3, 201);
  return 0;
}
