// localize_offline: runs the localizer's core code path over recorded data, as fast as the machine allows.
//   localize_offline --map PATH --query PATH --output results.csv [--params params.yaml]
//                    [--method dtw|seqslam] [--topic TOPIC] [--save-map MAP_FILE]
// PATH: a folder of images (file-name order; every map image is a keyframe), a bag with an image topic,
// or a map file written by the map recorder.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cstdlib>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "along_route_localization/localizer.h"
#include "along_route_localization/parameters.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_map.h"
#include "glue/frame_source.h"
#include "glue/map_io.h"

namespace alr = along_route_localization;

namespace
{

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start)
{
  return std::chrono::duration<double>(Clock::now() - start).count();
}

void usage(std::ostream& out, bool with_advanced = false)
{
  out << "usage: localize_offline --map PATH --query PATH --output results.csv [--params params.yaml]\n"
         "                        [--method dtw|seqslam] [--topic TOPIC] [--set name=value ...]\n"
         "                        [--save-map MAP_FILE] [--progress auto|bar|lines|off] [--quiet]\n"
         "       localize_offline --check-params [--params params.yaml] [--method dtw|seqslam] [--set name=value ...]\n"
         "       localize_offline --help | --help-advanced\n"
         "  PATH: a folder of images (sorted by file name), a bag with an image topic (sensor_msgs/Image, or\n"
         "        CompressedImage as image_transport's compressed plugin records it), or a map file\n"
         "        written by the map recorder (its stored preprocessing parameters are used; any given\n"
         "        with --params or --set must agree with them; as --query, its keyframes are the queries,\n"
         "        used as stored). No output may be written inside an input folder.\n"
         "  --save-map: also write the loaded map as a map file (the recorder's format: for the localizer\n"
         "        nodelet, or a later --map that skips decoding and preprocessing the images).\n"
         "  --params: YAML of 'name: value' lines, flat or in the launch files' sections (preprocessor:,\n"
         "        localizer:, map_recorder:, route_follower:; the last two are checked, not used). A value that\n"
         "        does not parse, an unknown name or one under another nodelet's section is refused and a\n"
         "        number outside its range is corrected, each with a warning; the others are used. --set\n"
         "        overrides one parameter (any problem with it is an error).\n"
         "  --check-params: check --params, --method and --set as a run on folders or bags of images does, then\n"
         "        exit: 0 if it takes them, 2 with the reason if not (what a map file's own preprocessing or\n"
         "        the map's length refuses, such as a start_keyframe beyond it, is checked by the run).\n"
         "  --progress: on stderr, while loading and localizing: a line redrawn in place (bar), a line at every\n"
         "        10 % (lines), nothing (off); auto (default): bar on a terminal, else lines after 2 s; off with --quiet.\n"
         "  Output CSV columns: query_index,keyframe,confidence,shift_px,homing_angle_rad,status\n"
         "\nParameters (name = default  (range unit), then what it is"
      << (with_advanced ? "; the advanced ones after each group's" : "; those a user sets for the robot and route")
      << "):\n"
      << alr::parameterHelp({ alr::ParameterGroup::kPreprocessor, alr::ParameterGroup::kLocalizer }, with_advanced,
                            "localize_offline --help-advanced");
}

// Progress of a stage on stderr (stdout may carry the results: --output /dev/stdout). kBar: a line redrawn
// in place, at most 10 times a second; kLines: a line at every 10 %; kAuto: kBar on a terminal, else kLines
// once the stage has taken 2 s (a short run in a log stays quiet); kOff: nothing (--quiet).
enum class ProgressMode
{
  kAuto,
  kBar,
  kLines,
  kOff
};

class Progress
{
public:
  Progress(const char* label, ProgressMode mode) : label_(label), mode_(mode), start_(Clock::now())
  {
    if (mode_ == ProgressMode::kAuto)
    {
      const bool terminal = isatty(2);
      mode_ = terminal ? ProgressMode::kBar : ProgressMode::kLines;
      quiet_seconds_ = terminal ? 0.0 : 2.0;
    }
  }
  void update(size_t done, size_t total)
  {
    if (mode_ == ProgressMode::kOff || total == 0)
      return;
    const double elapsed = secondsSince(start_);
    if (mode_ == ProgressMode::kBar)
    {
      if (done < total && drawn_ && elapsed - drawn_at_ < 0.1)
        return;
      drawn_ = true;
      drawn_at_ = elapsed;
      const int width = 30;
      const int filled = static_cast<int>(width * done / total);
      std::fprintf(stderr, "\rlocalize_offline: %-20s [%s%s] %zu/%zu", label_, std::string(filled, '#').c_str(),
                   std::string(width - filled, ' ').c_str(), done, total);
      if (done == total)
        std::fprintf(stderr, "\n");
      return;
    }
    const size_t tenths = 10 * done / total;
    if (tenths <= tenths_ || elapsed < quiet_seconds_)
      return;
    tenths_ = tenths;
    std::fprintf(stderr, "localize_offline: %s %zu/%zu (%zu %%), %.1f s\n", label_, done, total, 100 * done / total,
                 elapsed);
  }

private:
  const char* label_;
  ProgressMode mode_;
  Clock::time_point start_;
  double quiet_seconds_ = 0.0;
  bool drawn_ = false;
  double drawn_at_ = 0.0;
  size_t tenths_ = 0;
};

// Whether two paths name the same existing file (hard links and symlinks included).
bool sameFile(const std::string& a, const std::string& b)
{
  struct stat sa, sb;
  return stat(a.c_str(), &sa) == 0 && stat(b.c_str(), &sb) == 0 && sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

// Whether writing `path` would put a file into the folder `folder` or a folder under it (an input folder
// of images, whose every image file is read: a results file named like a frame replaced it). False when
// `folder` is not a folder.
bool insideFolder(const std::string& path, const std::string& folder)
{
  struct stat st;
  if (stat(folder.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
    return false;
  const size_t slash = path.find_last_of('/');
  const std::string parent = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
  char parent_real[PATH_MAX], folder_real[PATH_MAX];
  if (!realpath(parent.c_str(), parent_real) || !realpath(folder.c_str(), folder_real))
    return false;
  const std::string inner(parent_real), outer(folder_real);
  return inner == outer || (inner.size() > outer.size() && inner.compare(0, outer.size(), outer) == 0 &&
                            (outer == "/" || inner[outer.size()] == '/'));
}

// Where the results are written before they replace `path`: a file beside it, renamed over it once
// every row is written, so a failed run leaves an earlier results file as it was. Devices and pipes
// (/dev/stdout) are written directly.
std::string stagingPath(const std::string& path)
{
  struct stat st;
  if (stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    return path;
  return path + ".partial." + std::to_string(getpid());
}

}  // namespace

int main(int argc, char** argv)
{
  std::string map_path, query_path, output_path, params_path, method, topic, save_map_path;
  std::vector<std::pair<std::string, std::string>> overrides;
  bool quiet = false;
  bool check_params_only = false;
  ProgressMode progress_mode = ProgressMode::kAuto;
  bool progress_given = false;
  for (int i = 1; i < argc; ++i)
  {
    const std::string arg = argv[i];
    const auto value = [&]() -> std::string {
      if (i + 1 >= argc)
      {
        std::cerr << "localize_offline: " << arg << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "--map")
      map_path = value();
    else if (arg == "--query")
      query_path = value();
    else if (arg == "--output")
      output_path = value();
    else if (arg == "--params")
      params_path = value();
    else if (arg == "--method")
      method = value();
    else if (arg == "--topic")
      topic = value();
    else if (arg == "--save-map")
      save_map_path = value();
    else if (arg == "--set")
    {
      const std::string kv = value();
      const size_t eq = kv.find('=');
      if (eq == std::string::npos)
      {
        std::cerr << "localize_offline: --set takes name=value, got '" << kv << "'\n";
        return 2;
      }
      overrides.emplace_back(kv.substr(0, eq), kv.substr(eq + 1));
    }
    else if (arg == "--quiet")
      quiet = true;
    else if (arg == "--check-params")
      check_params_only = true;
    else if (arg == "--progress")
    {
      const std::string mode = value();
      progress_given = true;
      if (mode == "auto" || mode == "bar" || mode == "lines" || mode == "off")
        progress_mode = mode == "auto" ? ProgressMode::kAuto :
                        mode == "bar"  ? ProgressMode::kBar :
                        mode == "lines" ? ProgressMode::kLines :
                                          ProgressMode::kOff;
      else
      {
        std::cerr << "localize_offline: --progress takes auto, bar, lines or off, got '" << mode << "'\n";
        return 2;
      }
    }
    else if (arg == "-h" || arg == "--help")
    {
      usage(std::cout);
      return 0;
    }
    else if (arg == "--help-advanced")
    {
      usage(std::cout, true);
      return 0;
    }
    else
    {
      std::cerr << "localize_offline: unknown argument '" << arg << "'\n";
      usage(std::cerr);
      return 2;
    }
  }
  if (quiet && !progress_given)
    progress_mode = ProgressMode::kOff;
  if (check_params_only && !(map_path.empty() && query_path.empty() && output_path.empty() && save_map_path.empty()))
  {
    std::cerr << "localize_offline: --check-params reads no map, query or output: give them to a run instead\n";
    return 2;
  }
  if (!check_params_only && (map_path.empty() || query_path.empty() || output_path.empty()))
  {
    std::cerr << "localize_offline: --map, --query and --output are required\n";
    usage(std::cerr);
    return 2;
  }

  alr::PreprocessingParams preprocessing;
  alr::LocalizerParams localizer_params;
  std::string error;
  std::vector<alr::ParameterEntry> file_entries;  // read once: applied again below over a map file's parameters
  std::vector<std::string> refused;  // entries not taken as given: each named, the others used
  if (!params_path.empty() &&
      !(alr::readParameterFile(params_path, &file_entries, &error) &&
        alr::applyParameterEntriesChecked(params_path, file_entries, &preprocessing, &localizer_params, &refused,
                                          &error)))
  {
    std::cerr << "localize_offline: " << error << "\n";
    return 2;
  }
  for (const std::string& sentence : refused)
    std::cerr << "localize_offline: warning: " << sentence << "\n";
  for (const auto& kv : overrides)
  {
    // One value typed by hand: any problem with it is an error, a number outside its range too.
    alr::ParameterSet checked;
    const bool parsed = alr::applyParameter(kv.first, kv.second, &preprocessing, &localizer_params, &error);
    if (parsed && !alr::setParameterChecked(kv.first, kv.second, &checked).empty())
      error = "parameter '" + kv.first + "' must be in " + alr::findParameter(kv.first)->rangeText() + ", got " +
              kv.second;
    if (!parsed || !error.empty())
    {
      std::cerr << "localize_offline: --set: " << error << "\n";
      return 2;
    }
  }
  const std::string invalid_preprocessing = preprocessing.validate();
  if (!invalid_preprocessing.empty())
  {
    std::cerr << "localize_offline: invalid preprocessing parameters: " << invalid_preprocessing << "\n";
    return 2;
  }
  if (!method.empty() && !alr::sequenceMethodFromString(method, &localizer_params.method))
  {
    std::cerr << "localize_offline: --method must be dtw or seqslam, got '" << method << "'\n";
    return 2;
  }
  const std::string invalid = localizer_params.validate();
  if (!invalid.empty())
  {
    std::cerr << "localize_offline: invalid localizer parameters: " << invalid << "\n";
    return 2;
  }
  if (check_params_only)
  {
    // What the images' size refuses, for images preprocessed with these parameters (a map file brings its
    // own, checked by the run).
    const std::string invalid_for_images = localizer_params.validateForImages(preprocessing);
    if (!invalid_for_images.empty())
    {
      std::cerr << "localize_offline: invalid localizer parameters: " << invalid_for_images << "\n";
      return 2;
    }
    // A warning above (a --params entry corrected or skipped) is not a refusal: a run goes on with it too.
    if (refused.empty())
      std::cout << "localize_offline: the parameters are valid\n";
    else
      std::cout << "localize_offline: a run takes these parameters, with the " << refused.size()
                << (refused.size() == 1 ? " warning" : " warnings") << " above about " << params_path
                << " (values corrected, entries skipped)\n";
    return 0;
  }
  // No output may replace an input or the other output (a results file written over the query bag lost
  // the drive).
  struct Named
  {
    const char* option;
    const std::string& path;
  };
  const Named map_in{ "--map", map_path }, query_in{ "--query", query_path }, results_out{ "--output", output_path },
      map_out{ "--save-map", save_map_path };
  const std::pair<Named, Named> clashes[] = {
    { results_out, map_in }, { results_out, query_in }, { map_out, map_in }, { map_out, query_in }, { map_out, results_out }
  };
  for (const auto& clash : clashes)
  {
    const Named &a = clash.first, &b = clash.second;
    if (!a.path.empty() && (a.path == b.path || sameFile(a.path, b.path)))
    {
      std::cerr << "localize_offline: " << a.option << " '" << a.path << "' names the same file as " << b.option
                << "; choose another file\n";
      return 2;
    }
    const bool input = b.option == map_in.option || b.option == query_in.option;
    if (!a.path.empty() && input && insideFolder(a.path, b.path))
    {
      std::cerr << "localize_offline: " << a.option << " '" << a.path << "' is inside the " << b.option
                << " folder '" << b.path << "', whose images are the input; write it outside that folder\n";
      return 2;
    }
  }

  const auto start = Clock::now();
  std::shared_ptr<alr::RouteMap> map;
  std::vector<cv::Mat> queries;
  std::vector<int64_t> query_stamps;  // ns; 0 (unknown) for a folder
  try
  {
    // A recorder map carries the preprocessing it was made with, and the queries must be preprocessed
    // the same way: preprocessing parameters given for the run must agree with it.
    Progress map_progress("loading the map", progress_mode);
    map = alr::loadMapFromPath(map_path, topic, &preprocessing,
                               [&](size_t done, size_t total) { map_progress.update(done, total); });
    if (map->empty())
      throw alr::MapError("the map '" + map_path + "' holds no keyframes");
    // Only the names given count: the same file and --set applied over the map's parameters (with no
    // preprocessing name among them, that leaves the map's parameters as they are).
    alr::PreprocessingParams given = preprocessing;
    alr::LocalizerParams unused;
    std::vector<std::string> said;  // the same sentences as above
    alr::applyParameterEntriesChecked(params_path, file_entries, &given, &unused, &said, &error);
    for (const auto& kv : overrides)
      alr::applyParameter(kv.first, kv.second, &given, &unused, &error);
    if (!(given == preprocessing))
    {
      std::cerr << "localize_offline: the map file '" << map_path << "' was made with other preprocessing parameters "
                << "than those given (" << alr::preprocessingDifference(preprocessing, given)
                << ", map vs given); the queries are preprocessed as the map was, so leave them out, or give "
                   "--map the images to preprocess them anew\n";
      return 2;
    }
    Progress query_progress("loading the queries", progress_mode);
    queries = alr::loadPreprocessedFrames(query_path, topic, preprocessing, &query_stamps,
                                          [&](size_t done, size_t total) { query_progress.update(done, total); });
    if (queries.empty())
      throw alr::MapError("the query '" + query_path + "' holds no images");
  }
  catch (const std::exception& e)
  {
    std::cerr << "localize_offline: " << e.what() << "\n";
    return 1;
  }
  const double load_seconds = secondsSince(start);
  // The localizer (its per-map tables) before anything is written: parameters the map cannot take
  // (start_keyframe beyond it, max_shift_px over half its width) are refused with no map file saved.
  const auto localize_start = Clock::now();
  std::unique_ptr<alr::Localizer> localizer;
  try
  {
    localizer.reset(new alr::Localizer(map, localizer_params));  // the per-map tables (map statistics)
    localizer->measureMapStatisticsNow();                         // and the ones a check would measure on need
  }
  catch (const std::exception& e)
  {
    std::cerr << "localize_offline: " << e.what() << "\n";
    return 1;
  }
  const double tables_seconds = secondsSince(localize_start);
  if (!save_map_path.empty())
  {
    try
    {
      alr::writeMap(save_map_path, *map);
    }
    catch (const std::exception& e)
    {
      std::cerr << "localize_offline: --save-map: " << e.what() << "\n";
      return 1;
    }
    if (!quiet)
      std::cerr << "localize_offline: wrote the map (" << map->size() << " keyframes) to " << save_map_path << "\n";
  }

  const std::string staging = stagingPath(output_path);
  std::ofstream out(staging);
  if (!out)
  {
    std::cerr << "localize_offline: cannot write '" << output_path << "': " << std::strerror(errno) << "\n";
    return 1;
  }
  const auto fail = [&](const std::string& message) {
    std::cerr << "localize_offline: " << message << "\n";
    out.close();
    if (staging != output_path)
      std::remove(staging.c_str());
    return 1;
  };
  out << "query_index,keyframe,confidence,shift_px,homing_angle_rad,status\n";
  const auto frames_start = Clock::now();
  alr::FrameGapCounts gaps;
  int64_t restarts = 0;
  try
  {
    Progress progress("localizing", progress_mode);
    char line[160];
    for (size_t q = 0; q < queries.size(); ++q)
    {
      // As the localizer nodelet: a bag's stamps tell when time went back and when frames were missed.
      const alr::LocalizationResult r = localizer->process(queries[q], query_stamps[q]);
      restarts += r.time_went_back ? 1 : 0;
      gaps.add(r);
      std::snprintf(line, sizeof(line), "%zu,%d,%.6f,%.4f,%.6f,%s\n", q, r.keyframe, r.confidence, r.shift_px,
                    r.homing_angle_rad, alr::toString(r.status).c_str());
      out << line;
      progress.update(q + 1, queries.size());
    }
  }
  catch (const std::exception& e)
  {
    return fail(e.what());
  }
  const double localize_seconds = tables_seconds + secondsSince(frames_start);
  out.close();
  if (!out)  // e.g. a full disk: the rows did not all reach the file
    return fail("writing '" + staging + "' failed: " + std::strerror(errno) + "; '" + output_path + "' is left as it was");
  if (staging != output_path && std::rename(staging.c_str(), output_path.c_str()) != 0)
    return fail("cannot move '" + staging + "' to '" + output_path + "': " + std::strerror(errno));
  std::string stamps;
  if (gaps.gaps > 0)
    stamps += ", " + std::to_string(gaps.gaps) + " gaps in the stamps (" + std::to_string(gaps.missed_frames) +
              " frames missed" + (localizer_params.fill_frame_gaps ? "" : ", not filled in: fill_frame_gaps is off") +
              (gaps.searched_again > 0 ?
                   "; " + std::to_string(gaps.searched_again) + " longer than the window, searched again" :
                   "") +
              (gaps.stood_still > 0 ?
                   "; " + std::to_string(gaps.stood_still) + " with the same view before and after, not filled in" :
                   "") +
              ")";
  if (restarts > 0)
    stamps += ", " + std::to_string(restarts) + " restarts (time went back)";
  std::fprintf(stderr,
               "localize_offline: %zu keyframes, %zu queries%s, method %s: loading %.3f s, localizing %.3f s "
               "(%.3f ms/frame; the localizer's per-map tables %.3f s of it), total %.3f s -> %s\n",
               map->size(), queries.size(), stamps.c_str(), alr::toString(localizer_params.method).c_str(),
               load_seconds, localize_seconds, 1000.0 * localize_seconds / queries.size(), tables_seconds,
               secondsSince(start), output_path.c_str());
  return 0;
}
