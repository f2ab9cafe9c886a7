#include "glue/frame_source.h"

#include <sys/stat.h>

#include <algorithm>
#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>

#include <boost/filesystem.hpp>
#include <cv_bridge/cv_bridge.h>
#include <ros/exception.h>
#include <opencv2/imgcodecs.hpp>
#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>

#include "glue/image_message.h"
#include "glue/map_io.h"

namespace along_route_localization
{

namespace
{

namespace fs = boost::filesystem;

bool isImageFile(const fs::path& path)
{
  static const std::set<std::string> kExtensions = { ".png", ".jpg", ".jpeg", ".bmp", ".pgm", ".ppm", ".tif", ".tiff" };
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return kExtensions.count(ext) > 0;
}

/// Format of an image as cv::imread(IMREAD_UNCHANGED) returns it.
PixelFormat formatOfDecoded(const cv::Mat& image, const std::string& file)
{
  switch (image.type())
  {
    case CV_8UC1:
      return PixelFormat::kMono8;
    case CV_16UC1:
      return PixelFormat::kMono16;
    case CV_8UC3:
      return PixelFormat::kBgr8;
    case CV_8UC4:
      return PixelFormat::kBgra8;
    default:
      throw std::runtime_error("unsupported pixel type " + cv::typeToString(image.type()) + " in '" + file + "'");
  }
}

/// Each frame is resized to the output, so frames of several sizes localize; but one camera's frames have one
/// size, and two sizes are most likely two cameras' (or a folder of other images) mixed: said once, as a
/// warning. name(i): how frame i is named in it.
void warnOfOtherSizes(const std::vector<cv::Size>& sizes, const std::function<std::string(size_t)>& name,
                      const std::string& noun)
{
  if (sizes.empty())
    return;
  size_t other = 0, first_other = 0;
  for (size_t i = 1; i < sizes.size(); ++i)
    if (sizes[i] != sizes[0] && other++ == 0)
      first_other = i;
  if (other > 0)
    std::cerr << "warning: " << other << " of the " << sizes.size() << " " << noun << " are not the size of the first ("
              << name(0) << ", " << sizes[0].width << "x" << sizes[0].height << "), e.g. " << name(first_other) << ", "
              << sizes[first_other].width << "x" << sizes[first_other].height
              << ": each is resized to the output, but one camera's frames have one size (two cameras mixed?)\n";
}

/// Reads and preprocesses files in parallel, one Preprocessor per worker.
std::vector<cv::Mat> preprocessFiles(const std::vector<std::string>& files, const PreprocessingParams& params,
                                     const LoadProgress& progress)
{
  std::mutex progress_mutex;
  size_t done = 0;  // files read, under progress_mutex
  std::vector<cv::Mat> frames(files.size());
  std::vector<std::string> errors(files.size());
  std::vector<cv::Size> sizes(files.size());
  cv::parallel_for_(cv::Range(0, static_cast<int>(files.size())), [&](const cv::Range& range) {
    Preprocessor preprocessor(params);
    for (int i = range.start; i < range.end; ++i)
    {
      const cv::Mat image = cv::imread(files[i], cv::IMREAD_UNCHANGED);
      if (image.empty())
      {
        errors[i] = "cannot read image '" + files[i] + "'";
        continue;
      }
      sizes[i] = image.size();
      try
      {
        preprocessor.process(image, formatOfDecoded(image, files[i]), frames[i]);
      }
      catch (const std::exception& e)
      {
        errors[i] = files[i] + ": " + e.what();
      }
      if (progress)
      {
        std::lock_guard<std::mutex> lock(progress_mutex);
        progress(++done, files.size());
      }
    }
  });
  for (const std::string& error : errors)
    if (!error.empty())
      throw std::runtime_error(error);
  warnOfOtherSizes(sizes, [&](size_t i) { return "'" + files[i] + "'"; }, "images");
  const auto smaller = [&](const cv::Size& size) {
    return inputSmallerThanOutput(size.width, size.height, params, nullptr);
  };
  const auto first = std::find_if(sizes.begin(), sizes.end(), smaller);
  if (first != sizes.end())
  {
    std::string sentence;
    inputSmallerThanOutput(first->width, first->height, params, &sentence);
    const auto count = std::count_if(first, sizes.end(), smaller);
    std::cerr << "warning: '" << files[first - sizes.begin()] << "' is a " << first->width << "x" << first->height
              << " image " << sentence << "; smaller than the output: " << count << " of the " << files.size()
              << " images\n";
  }
  return frames;
}

std::string imageTopicOf(rosbag::Bag& bag, const std::string& path, const std::string& topic)
{
  if (!topic.empty())
    return topic;
  std::set<std::string> topics;
  rosbag::View view(bag);
  if (view.size() == 0)  // e.g. a cut map that `rosbag reindex` could keep nothing of
    throw std::runtime_error("bag '" + path + "' holds no messages");
  for (const rosbag::ConnectionInfo* info : view.getConnections())
    if (info->datatype == "sensor_msgs/Image" || info->datatype == "sensor_msgs/CompressedImage")
      topics.insert(info->topic);
  if (topics.size() != 1)
  {
    std::string names;
    for (const std::string& t : topics)
      names += " " + t;
    throw std::runtime_error("bag '" + path + "' has " + std::to_string(topics.size()) +
                             " image topics, sensor_msgs/Image or CompressedImage (" +
                             (names.empty() ? " none" : names) + " ); choose one with --topic");
  }
  return *topics.begin();
}

/// The error for a file rosbag cannot open: rosbag's own words (`e`, e.g. "wanted 4 bytes, read 0 bytes") do
/// not say what is wrong with the file.
std::runtime_error unreadableBag(const std::string& path, const std::exception& e)
{
  switch (bagFileHead(path))
  {
    case BagFileHead::kEmpty:
      return std::runtime_error("'" + path + "' is empty (0 bytes): neither a bag nor a map file");
    case BagFileHead::kNotABag:
      return std::runtime_error("'" + path + "' is not a bag or map file (nor a folder of images)");
    case BagFileHead::kOtherVersion:
      return std::runtime_error("'" + path + "' is a rosbag of another format version than 2.0");
    case BagFileHead::kCutInHeader:
      return std::runtime_error("'" + path + "' is cut short inside the bag header (" +
                                std::to_string(fs::file_size(path)) + " bytes): nothing to recover");
    case BagFileHead::kRosbag2:
      break;
  }
  return std::runtime_error("bag '" + path + "' cannot be read, probably cut short (a recording that was "
                            "interrupted?): `rosbag reindex " + path + "` may recover it. rosbag says: " + e.what());
}

/// A file given for frames, opened once: a recorder map file (map_io.h) is read as the map and returned, `bag`
/// closed; any other bag is left open in `bag` for preprocessBag, and null returned. Throws, saying what the
/// file is, when rosbag cannot open it and it is no map file either.
std::shared_ptr<RouteMap> openMapOrImageBag(const std::string& path, rosbag::Bag* bag)
{
  try
  {
    bag->open(path, rosbag::bagmode::Read);
  }
  catch (const std::exception& e)
  {
    // rosbag needs the index at the end of the file; the map reader walks the records and also reads a
    // map whose index was never written (copied or written while the disk filled up).
    if (bagFileHead(path) == BagFileHead::kRosbag2)
    {
      try
      {
        return std::make_shared<RouteMap>(readMap(path));
      }
      catch (const MapError&)
      {
      }
    }
    throw unreadableBag(path, e);
  }
  // A map is known by any of its own topics (relative names, which no recorded topic has): one that lost
  // its parameters (a damaged index, a `rosbag filter`) is refused by readMap, not preprocessed again as
  // an image bag.
  rosbag::View view(*bag, rosbag::TopicQuery(std::vector<std::string>{ kMapPreprocessingTopic, kMapKeyframesTopic,
                                                                       kMapInfoTopic }));
  if (view.size() == 0)
    return nullptr;
  bag->close();
  return std::make_shared<RouteMap>(readMap(path));
}

/// Preprocessed frames of an image topic of `bag` (open, read from `path`), with their header stamps in ns.
std::vector<cv::Mat> preprocessBag(rosbag::Bag& bag, const std::string& path, const std::string& topic,
                                   const PreprocessingParams& params, std::vector<int64_t>* stamps_ns,
                                   const LoadProgress& progress)
{
  const std::string image_topic = imageTopicOf(bag, path, topic);
  rosbag::View view(bag, rosbag::TopicQuery(image_topic));
  if (view.size() == 0)
    throw std::runtime_error("bag '" + path + "' has no messages on topic '" + image_topic + "'");
  Preprocessor preprocessor(params);
  std::vector<cv::Mat> frames;
  std::vector<cv::Size> sizes;
  size_t clipped_frames = 0, enlarged_frames = 0;
  // rosbag's words for a damaged message ("Buffer Overrun", "Unknown connection ID: 255") name neither the
  // file nor the message: said here with both.
  const auto damaged = [&](size_t position, const std::exception& e) {
    return std::runtime_error("bag '" + path + "' is damaged at message " + std::to_string(position) + " of topic '" +
                              image_topic + "' (rosbag says: " + e.what() + ")" +
                              (position > 0 ? "; the " + std::to_string(position) +
                                                  " messages before it read well (`rosbag filter` can copy them)" :
                                              std::string()));
  };
  try
  {
    for (const rosbag::MessageInstance& m : view)
    {
      // Which message, for every error below: the bag, the topic, its 0-based position there, its stamp.
      const size_t position = frames.size();
      const auto where = [&] {
        std::ostringstream text;
        text << "'" << path << "', topic '" << image_topic << "', message " << position << " (bag time "
             << m.getTime() << ")";
        return text.str();
      };
      // The image as the camera gave it, and its header: a sensor_msgs/Image wrapped as it is, or a
      // CompressedImage (what image_transport's compressed plugin and many camera bags hold) decoded.
      cv::Mat pixels;
      PixelFormat format;
      std_msgs::Header header;
      cv_bridge::CvImageConstPtr wrapped;  // keeps a wrapped Image's data alive
      const sensor_msgs::Image::ConstPtr msg = m.instantiate<sensor_msgs::Image>();
      const sensor_msgs::CompressedImage::ConstPtr compressed_msg =
          msg ? sensor_msgs::CompressedImage::ConstPtr() : m.instantiate<sensor_msgs::CompressedImage>();
      if (msg)
      {
        std::string problem;
        if (imageMessageProblem(*msg, &format, &problem) != ImageProblem::kNone)
          throw std::runtime_error(where() + ": " + problem);
        try
        {
          wrapped = cv_bridge::toCvShare(msg);
        }
        catch (const std::exception& e)  // cv_bridge::Exception
        {
          throw std::runtime_error(where() + ": " + e.what());
        }
        pixels = wrapped->image;
        header = msg->header;
      }
      else if (compressed_msg)
      {
        if (!compressed_msg->data.empty())
          pixels = cv::imdecode(compressed_msg->data, cv::IMREAD_UNCHANGED);
        if (pixels.empty())
          throw std::runtime_error(where() + ": its " + std::to_string(compressed_msg->data.size()) +
                                   " bytes of format '" + compressed_msg->format +
                                   "' do not decode as an image (a compressedDepth image, or damaged data)");
        format = formatOfDecoded(pixels, where());
        header = compressed_msg->header;
      }
      else
      {
        throw std::runtime_error(where() + ": not a sensor_msgs/Image or CompressedImage but " + m.getDataType());
      }
      try
      {
        std::string warning;
        if (format == PixelFormat::kMono32F && floatOutsideUnitRange(pixels, &warning) && clipped_frames++ == 0)
          std::cerr << "warning: " << where() << ": " << warning << " (scale the images to [0, 1]); "
                    << "the bag's other such frames are counted, not named\n";
        if (inputSmallerThanOutput(pixels.cols, pixels.rows, params, &warning) && enlarged_frames++ == 0)
          std::cerr << "warning: " << where() << ": a " << pixels.cols << "x" << pixels.rows << " image " << warning
                    << "; the bag's other such frames are counted, not named\n";
        sizes.push_back(pixels.size());
        frames.emplace_back();
        preprocessor.process(pixels, format, frames.back());
      }
      catch (const std::exception& e)  // PreprocessingError (e.g. NaN pixels)
      {
        throw std::runtime_error(where() + ": " + e.what());
      }
      if (stamps_ns)
        stamps_ns->push_back(static_cast<int64_t>(header.stamp.toNSec()));
      if (progress)
        progress(frames.size(), view.size());
    }
  }
  catch (const ros::Exception& e)  // reading or decoding a message: rosbag's and the deserializer's (not ours)
  {
    throw damaged(frames.size(), e);
  }
  warnOfOtherSizes(sizes, [&](size_t i) { return "message " + std::to_string(i); },
                   "frames of '" + path + "', topic '" + image_topic + "',");
  if (clipped_frames > 1)
    std::cerr << "warning: '" << path << "', topic '" << image_topic << "': " << clipped_frames << " of "
              << frames.size() << " 32FC1 frames had values outside [0, 1], clipped\n";
  if (enlarged_frames > 1)
    std::cerr << "warning: '" << path << "', topic '" << image_topic << "': " << enlarged_frames << " of "
              << frames.size() << " frames were smaller than the output, enlarged\n";
  return frames;
}

bool isDirectory(const std::string& path)
{
  return fs::is_directory(fs::path(path));
}

void requireExists(const std::string& path)
{
  struct stat info;
  if (stat(path.c_str(), &info) != 0)
    throw std::runtime_error("'" + path + "' does not exist");
}

}  // namespace

std::vector<std::string> listImageFiles(const std::string& folder)
{
  std::vector<std::string> files;
  for (const fs::directory_entry& entry : fs::directory_iterator(fs::path(folder)))
    if (fs::is_regular_file(entry.status()) && isImageFile(entry.path()))
      files.push_back(entry.path().string());
  std::sort(files.begin(), files.end());
  return files;
}

std::vector<cv::Mat> loadPreprocessedFrames(const std::string& path, const std::string& topic,
                                            const PreprocessingParams& params, std::vector<int64_t>* stamps_ns,
                                            const LoadProgress& progress)
{
  requireExists(path);
  if (stamps_ns)
    stamps_ns->clear();
  if (isDirectory(path))
  {
    const std::vector<std::string> files = listImageFiles(path);
    if (files.empty())
      throw std::runtime_error("folder '" + path + "' holds no image files");
    if (stamps_ns)
      stamps_ns->assign(files.size(), 0);
    return preprocessFiles(files, params, progress);
  }
  rosbag::Bag bag;
  if (const std::shared_ptr<RouteMap> map = openMapOrImageBag(path, &bag))
  {
    // A map file's keyframes are preprocessed already: used as they are, when made as these frames must be.
    if (!(map->params() == params))
      throw std::runtime_error("the map file '" + path + "' was made with other preprocessing parameters than " +
                               "these frames need (" + preprocessingDifference(map->params(), params) +
                               ", file vs needed); give the images instead, to preprocess them anew");
    std::vector<cv::Mat> frames;
    frames.reserve(map->size());
    for (size_t i = 0; i < map->size(); ++i)
    {
      frames.push_back(map->keyframeMat(i).clone());
      if (stamps_ns)
        stamps_ns->push_back(map->stampNs(i));
      if (progress)
        progress(i + 1, map->size());
    }
    if (frames.empty())
      throw std::runtime_error("the map file '" + path + "' holds no keyframes");
    return frames;
  }
  return preprocessBag(bag, path, topic, params, stamps_ns, progress);
}

std::shared_ptr<RouteMap> loadMapFromPath(const std::string& path, const std::string& topic, PreprocessingParams* params,
                                          const LoadProgress& progress)
{
  requireExists(path);
  rosbag::Bag bag;  // an image bag: opened once, to tell it from a map file and then to read its images
  if (!isDirectory(path))
    if (std::shared_ptr<RouteMap> map = openMapOrImageBag(path, &bag))
    {
      *params = map->params();
      return map;
    }
  auto map = std::make_shared<RouteMap>(*params);
  std::vector<int64_t> stamps;
  std::vector<cv::Mat> frames;
  if (isDirectory(path))
  {
    const std::vector<std::string> files = listImageFiles(path);
    if (files.empty())
      throw std::runtime_error("folder '" + path + "' holds no image files");
    frames = preprocessFiles(files, *params, progress);
    for (size_t i = 0; i < frames.size(); ++i)
      stamps.push_back(static_cast<int64_t>(i));
  }
  else
  {
    frames = preprocessBag(bag, path, topic, *params, &stamps, progress);
    // Every image becomes a keyframe in bag order: a bag whose stamps go back (a drive recorded twice, a
    // loop) holds the route more than once, and each place then has a look-alike in the map.
    size_t back = 0, first_back = 0;
    for (size_t i = 1; i < stamps.size(); ++i)
      if (stamps[i] < stamps[i - 1] && back++ == 0)
        first_back = i;
    if (back > 0)
      std::cerr << "warning: the map bag '" << path << "': its stamps go back " << back << " time(s), first at message "
                << first_back << ": does it hold the drive more than once? Every image is a keyframe, in bag order\n";
  }
  map->reserve(frames.size());
  for (size_t i = 0; i < frames.size(); ++i)
    map->addKeyframe(frames[i], stamps[i]);
  return map;
}

}  // namespace along_route_localization
