// libFuzzer target: the map loader (readMap, src/glue/map_io.cpp) on arbitrary file contents.
// Built and run by scripts/run_sanitizers.sh with AddressSanitizer and UndefinedBehaviorSanitizer.
//
// A map file is whatever the user points the localizer at: readMap must turn every file into a RouteMap
// or a MapError, never a crash, a sanitizer report, an unbounded allocation or another exception.
// Seeds: valid maps written by writeMap (fuzz_seeds.cpp), generated at run time.
#include <stdlib.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "along_route_localization/route_map.h"
#include "glue/map_io.h"

namespace
{

std::string& mapPath()
{
  static std::string path;
  return path;
}

void removeMapFile()
{
  std::remove(mapPath().c_str());
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/)
{
  const char* dir = std::getenv("FUZZ_TMPDIR");
  mapPath() = std::string(dir != nullptr && dir[0] != '\0' ? dir : "/tmp") + "/along_route_fuzz_map_" +
              std::to_string(::getpid()) + ".bag";
  std::atexit(removeMapFile);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
  FILE* file = std::fopen(mapPath().c_str(), "wb");
  if (file == nullptr)
    __builtin_trap();  // the fuzzer's own temp file: nothing to learn without it
  if (size > 0 && std::fwrite(data, 1, size, file) != size)
    __builtin_trap();
  std::fclose(file);
  try
  {
    const along_route_localization::RouteMap map = along_route_localization::readMap(mapPath());
    // Touch every byte and stamp that was read, so a map that lies about its size shows up under ASan.
    unsigned checksum = 0;
    for (size_t k = 0; k < map.size(); ++k)
    {
      const uint8_t* keyframe = map.keyframe(k);
      for (size_t i = 0; i < map.keyframeBytes(); ++i)
        checksum += keyframe[i];
      checksum += static_cast<unsigned>(map.stampNs(k)) + static_cast<unsigned>(map.energy(k));
    }
    if (map.empty() || map.params().validate() != "")
      __builtin_trap();  // readMap promises a non-empty map with valid parameters
    volatile unsigned sink = checksum;
    (void)sink;
  }
  catch (const along_route_localization::MapError&)
  {
  }
  return 0;
}
