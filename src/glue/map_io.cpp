#include "glue/map_io.h"

#include <dirent.h>
#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <fstream>
#include <map>
#include <memory>
#include <mutex>
#include <new>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <vector>

#include <ros/console.h>
#include <ros/exception.h>
#include <ros/names.h>
#include <rosbag/bag.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <ros/serialization.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>

namespace along_route_localization
{
namespace
{

std::string inQuotes(const std::string& path)
{
  return "'" + path + "'";
}

bool fileExists(const std::string& path, struct stat* info)
{
  return ::stat(path.c_str(), info) == 0;
}

bool endsWith(const std::string& text, const std::string& end)
{
  return text.size() >= end.size() && text.compare(text.size() - end.size(), end.size(), end) == 0;
}

bool isMono8(const std::string& encoding)
{
  return encoding == sensor_msgs::image_encodings::MONO8 || encoding == sensor_msgs::image_encodings::TYPE_8UC1;
}

// Checks what can be told from the file system and the first bytes, before rosbag sees the file:
// rosbag's own messages for these cases ("Error opening file") do not say what is wrong.
void checkMapFile(const std::string& path)
{
  if (path.empty())
    throw MapError("no map file given (empty path)");
  struct stat info;
  if (!fileExists(path, &info))
  {
    struct stat active_info;
    if (fileExists(path + ".active", &active_info))
      throw MapError("map file " + inQuotes(path) + " does not exist, but " + inQuotes(path + ".active") +
                     " does: a recording was interrupted while it was writing; recover it with `rosbag reindex " +
                     path + ".active` and rename it to " + inQuotes(path));
    throw MapError("map file " + inQuotes(path) + " does not exist");
  }
  if (S_ISDIR(info.st_mode))
    throw MapError("map file " + inQuotes(path) + " is a directory, not a map file");
  if (info.st_size == 0)
    throw MapError("map file " + inQuotes(path) + " is empty (0 bytes)");

  if (!std::ifstream(path, std::ios::binary))
    throw MapError("map file " + inQuotes(path) + " cannot be opened: " + std::strerror(errno));
  switch (bagFileHead(path))
  {
    case BagFileHead::kRosbag2:
    case BagFileHead::kEmpty:  // not 0 bytes (above): the file changed under us, and the reader will say so
      return;
    case BagFileHead::kOtherVersion:
      throw MapError("map file " + inQuotes(path) + " is a rosbag of another format version than 2.0");
    case BagFileHead::kCutInHeader:
      throw MapError("map file " + inQuotes(path) + " is truncated (" + std::to_string(info.st_size) +
                     " bytes, not even a bag header)");
    case BagFileHead::kNotABag:
      break;
  }
  throw MapError("map file " + inQuotes(path) + " is not a rosbag (no '#ROSBAG V2.0' header): not a map file");
}

// The map reader walks the bag's records in file order instead of using rosbag's reader: a map file
// is written in map order, an unindexed bag (an interrupted flush) reads as well, and every length
// in a damaged file is checked before it is used (rosbag trusts them and may crash).
class CorruptMap : public std::runtime_error
{
public:
  using std::runtime_error::runtime_error;
};

/// Bounds-checked little-endian reads from a byte range.
class Cursor
{
public:
  Cursor(const char* data, size_t size) : data_(data), left_(size) {}
  size_t left() const { return left_; }
  const char* bytes(size_t count, const char* what)
  {
    if (count > left_)
      throw CorruptMap(std::string(what) + " claims " + std::to_string(count) + " bytes, " +
                       std::to_string(left_) + " are left");
    const char* start = data_;
    data_ += count;
    left_ -= count;
    return start;
  }
  uint32_t u32(const char* what)
  {
    const unsigned char* b = reinterpret_cast<const unsigned char*>(bytes(4, what));
    return static_cast<uint32_t>(b[0]) | static_cast<uint32_t>(b[1]) << 8 | static_cast<uint32_t>(b[2]) << 16 |
           static_cast<uint32_t>(b[3]) << 24;
  }
  uint8_t u8(const char* what) { return static_cast<uint8_t>(*bytes(1, what)); }
  std::string string(const char* what)
  {
    const uint32_t length = u32(what);
    return std::string(bytes(length, what), length);
  }

private:
  const char* data_;
  size_t left_;
};

using Fields = std::map<std::string, std::string>;

/// "length name=value" fields of a record header or a connection header.
Fields parseFields(const std::string& bytes)
{
  Fields fields;
  Cursor cursor(bytes.data(), bytes.size());
  while (cursor.left() > 0)
  {
    const uint32_t length = cursor.u32("a header field");
    const std::string field(cursor.bytes(length, "a header field"), length);
    const size_t equals = field.find('=');
    if (equals == std::string::npos)
      throw CorruptMap("a record header field has no '='");
    fields[field.substr(0, equals)] = field.substr(equals + 1);
  }
  return fields;
}

uint32_t fieldU32(const Fields& fields, const char* name)
{
  const auto it = fields.find(name);
  if (it == fields.end() || it->second.size() != 4)
    throw CorruptMap(std::string("a record lacks its 4-byte '") + name + "' field");
  Cursor cursor(it->second.data(), 4);
  return cursor.u32(name);
}

struct Record
{
  uint8_t op = 0;
  Fields fields;
  std::string data;
};

constexpr uint8_t kOpMessageData = 0x02;
constexpr uint8_t kOpBagHeader = 0x03;
constexpr uint8_t kOpIndexData = 0x04;
constexpr uint8_t kOpChunk = 0x05;
constexpr uint8_t kOpChunkInfo = 0x06;
constexpr uint8_t kOpConnection = 0x07;
constexpr uint32_t kMaxRecordHeaderBytes = 1 << 20;

Record makeRecord(const std::string& header, std::string data)
{
  Record record;
  record.fields = parseFields(header);
  const auto op = record.fields.find("op");
  if (op == record.fields.end() || op->second.size() != 1)
    throw CorruptMap("a record has no op code");
  record.op = static_cast<uint8_t>(op->second[0]);
  record.data = std::move(data);
  return record;
}

/// Records of a bag file, in file order; the file is never held in memory as a whole.
class RecordScanner
{
public:
  RecordScanner(std::ifstream& file, uint64_t size) : file_(file), size_(size), offset_(13) {}
  uint64_t offset() const { return offset_; }

  bool next(Record* record)
  {
    if (offset_ == size_)
      return false;
    const uint32_t header_length = readU32("a record header length");
    if (header_length > kMaxRecordHeaderBytes)
      throw CorruptMap("a record header claims " + std::to_string(header_length) + " bytes");
    const std::string header = readBytes(header_length, "a record header");
    const uint32_t data_length = readU32("a record data length");
    *record = makeRecord(header, readBytes(data_length, "a record"));
    return true;
  }

private:
  std::string readBytes(uint64_t count, const char* what)
  {
    if (count > size_ - offset_)
      throw CorruptMap(std::string("the file ends inside ") + what + " (it claims " + std::to_string(count) +
                       " bytes, " + std::to_string(size_ - offset_) + " are left)");
    std::string bytes(static_cast<size_t>(count), '\0');
    file_.read(&bytes[0], static_cast<std::streamsize>(count));
    if (static_cast<uint64_t>(file_.gcount()) != count)
      throw CorruptMap("reading failed at byte " + std::to_string(offset_));
    offset_ += count;
    return bytes;
  }
  uint32_t readU32(const char* what)
  {
    const std::string bytes = readBytes(4, what);
    Cursor cursor(bytes.data(), 4);
    return cursor.u32(what);
  }

  std::ifstream& file_;
  uint64_t size_;
  uint64_t offset_;
};

struct Connection
{
  std::string topic;
  std::string type;
};

/// Collects what a map file holds while its records stream by.
class MapContents
{
public:
  /// file_bytes: the map file's size, an upper bound of the keyframe bytes it holds. motion: where the
  /// taught motion goes (null: not read).
  MapContents(const std::string& path, uint64_t file_bytes, std::map<int, TaughtMotion>* motion)
    : path_(path), file_bytes_(file_bytes), motion_(motion)
  {
  }

  void connection(const Record& record)
  {
    const uint32_t id = fieldU32(record.fields, "conn");
    const Fields header = parseFields(record.data);
    const auto topic = record.fields.find("topic");
    const auto type = header.find("type");
    if (topic == record.fields.end() || type == header.end())
      throw CorruptMap("a connection record lacks its topic or type");
    connections_[id] = Connection{ topic->second, type->second };
  }

  void message(const Record& record)
  {
    const uint32_t id = fieldU32(record.fields, "conn");
    const auto connection = connections_.find(id);
    if (connection == connections_.end())
      throw CorruptMap("a message refers to connection " + std::to_string(id) + ", which is not defined");
    const Connection& c = connection->second;
    Cursor cursor(record.data.data(), record.data.size());
    if (c.topic == kMapKeyframesTopic)
    {
      if (c.type != "sensor_msgs/Image")
        throw MapError("map file " + inQuotes(path_) + ": topic '" + kMapKeyframesTopic + "' has type " + c.type +
                       ", expected sensor_msgs/Image");
      keyframe(cursor);
    }
    else if (c.topic == kMapMotionTopic && motion_)
    {
      if (c.type != "along_route_localization/KeyframeMotion")
        throw MapError("map file " + inQuotes(path_) + ": topic '" + kMapMotionTopic + "' has type " + c.type +
                       ", expected along_route_localization/KeyframeMotion");
      taughtMotion(record.data);
    }
    else if (c.topic == kMapPreprocessingTopic || c.topic == kMapInfoTopic)
    {
      if (c.type != "std_msgs/String")
        throw MapError("map file " + inQuotes(path_) + ": topic '" + c.topic + "' has type " + c.type +
                       ", expected std_msgs/String");
      const std::string text = cursor.string("a string message");
      if (c.topic == kMapInfoTopic)
        info(text);
      else
        preprocessing(text);
    }
  }

  /// The keyframes read so far (a cut or corrupt file: those before the damage).
  size_t keyframesRead() const { return map_.size() + early_keyframes_.size(); }

  /// The topics of the connections seen so far (sorted, each once).
  std::vector<std::string> topics() const
  {
    std::vector<std::string> names;
    for (const auto& c : connections_)
      names.push_back(c.second.topic);
    std::sort(names.begin(), names.end());
    names.erase(std::unique(names.begin(), names.end()), names.end());
    return names;
  }

  RouteMap finish()
  {
    if (!params_)
      throw MapError("map file " + inQuotes(path_) + " holds no preprocessing parameters (topic '" +
                     kMapPreprocessingTopic + "'): not a map written by the map recorder");
    if (map_.empty())
      throw MapError("map file " + inQuotes(path_) + " holds no keyframes (topic '" + kMapKeyframesTopic + "')");
    return std::move(map_);
  }

private:
  struct Keyframe
  {
    int64_t stamp_ns;
    uint32_t height, width, step;
    std::string encoding, data;
  };

  void info(const std::string& text)
  {
    int format = 0;
    if (std::sscanf(text.c_str(), "format=%d", &format) == 1 && format > kMapFormat)
      throw MapError("map file " + inQuotes(path_) + " has map format " + std::to_string(format) +
                     "; this version reads format " + std::to_string(kMapFormat) + " and older");
  }

  void preprocessing(const std::string& text)
  {
    if (params_)
    {
      if (text != params_text_)
        throw MapError("map file " + inQuotes(path_) + " holds two different preprocessing parameter sets: '" +
                       params_text_ + "' and '" + text + "'");
      return;
    }
    PreprocessingParams params;
    std::string error;
    if (!PreprocessingParams::parse(text, &params, &error))
      throw MapError("map file " + inQuotes(path_) + " has invalid preprocessing parameters '" + text + "': " + error);
    params_.reset(new PreprocessingParams(params));
    params_text_ = text;
    map_ = RouteMap(params);
    // Room for every keyframe the file can hold (each takes more file bytes than keyframe bytes): no
    // reallocation and copy of the growing map while it is read (most of the reading time of a big map).
    map_.reserve(static_cast<size_t>(file_bytes_ / std::max<size_t>(1, map_.keyframeBytes())));
    for (const Keyframe& keyframe : early_keyframes_)
      add(keyframe);
    early_keyframes_.clear();
  }

  void taughtMotion(const std::string& bytes)
  {
    KeyframeMotion recorded;
    try
    {
      ros::serialization::IStream stream(reinterpret_cast<uint8_t*>(const_cast<char*>(bytes.data())),
                                         static_cast<uint32_t>(bytes.size()));
      ros::serialization::deserialize(stream, recorded);
    }
    catch (const ros::Exception& e)
    {
      throw CorruptMap(std::string("a taught motion message is cut short: ") + e.what());
    }
    if (!std::isfinite(recorded.linear_mps) || !std::isfinite(recorded.angular_rps) ||
        !std::isfinite(recorded.distance_m))
      throw MapError("map file " + inQuotes(path_) + ": the taught motion of keyframe " +
                     std::to_string(recorded.keyframe) + " is not finite");
    TaughtMotion& taught = (*motion_)[static_cast<int>(std::min<uint32_t>(recorded.keyframe, 1u << 30))];
    taught.linear_mps = recorded.linear_mps;
    taught.angular_rps = recorded.angular_rps;
    taught.distance_m = recorded.distance_m;
  }

  void keyframe(Cursor& cursor)
  {
    Keyframe keyframe;
    cursor.u32("an image header");  // seq
    const uint32_t sec = cursor.u32("an image stamp");
    const uint32_t nsec = cursor.u32("an image stamp");
    keyframe.stamp_ns = static_cast<int64_t>(sec) * 1000000000LL + nsec;
    cursor.string("an image frame_id");
    keyframe.height = cursor.u32("an image height");
    keyframe.width = cursor.u32("an image width");
    keyframe.encoding = cursor.string("an image encoding");
    cursor.u8("an image is_bigendian");
    keyframe.step = cursor.u32("an image step");
    keyframe.data = cursor.string("an image's data");
    if (params_)
      add(keyframe);
    else
      early_keyframes_.push_back(std::move(keyframe));
  }

  void add(const Keyframe& keyframe)
  {
    const auto where = [&]() {
      return "map file " + inQuotes(path_) + ": keyframe " + std::to_string(map_.size());
    };
    if (!isMono8(keyframe.encoding))
      throw MapError(where() + " has encoding '" + keyframe.encoding + "', expected mono8");
    if (static_cast<int>(keyframe.width) != map_.width() || static_cast<int>(keyframe.height) != map_.height())
      throw MapError(where() + " is " + std::to_string(keyframe.width) + "x" + std::to_string(keyframe.height) +
                     " px, but the map's preprocessing makes " + std::to_string(map_.width()) + "x" +
                     std::to_string(map_.height()) + " px (inconsistent keyframe sizes)");
    if (keyframe.step < keyframe.width ||
        keyframe.data.size() < static_cast<uint64_t>(keyframe.step) * keyframe.height)
      throw MapError(where() + " is truncated: " + std::to_string(keyframe.data.size()) + " bytes for " +
                     std::to_string(keyframe.height) + " rows of step " + std::to_string(keyframe.step));
    const cv::Mat view(map_.height(), map_.width(), CV_8UC1, const_cast<char*>(keyframe.data.data()), keyframe.step);
    map_.addKeyframe(view, keyframe.stamp_ns);
  }

  std::string path_;
  uint64_t file_bytes_;
  std::map<int, TaughtMotion>* motion_;
  std::map<uint32_t, Connection> connections_;
  std::unique_ptr<PreprocessingParams> params_;
  std::string params_text_;
  RouteMap map_;
  std::vector<Keyframe> early_keyframes_;  // keyframes stored before the parameters (not by MapWriter)
};

}  // namespace

std::string replacedMapPath(const std::string& path, time_t modified)
{
  const size_t slash = path.find_last_of('/');
  const size_t dot = path.find_last_of('.');
  const bool has_extension = dot != std::string::npos && (slash == std::string::npos || dot > slash + 1);
  const std::string stem = has_extension ? path.substr(0, dot) : path;
  const std::string extension = has_extension ? path.substr(dot) : std::string();
  char when[32] = "unknown-time";
  struct tm local;
  if (localtime_r(&modified, &local))
    std::strftime(when, sizeof(when), "%Y-%m-%d-%H-%M-%S", &local);
  const std::string base = stem + ".replaced-" + when;
  struct stat info;
  std::string candidate = base + extension;
  for (int n = 2; fileExists(candidate, &info); ++n)
    candidate = base + "-" + std::to_string(n) + extension;
  return candidate;
}

std::string preprocessingParamsTopic(const std::string& resolved_image_topic)
{
  const std::string parent = ros::names::parentNamespace(resolved_image_topic);
  return parent == "/" ? "/preprocessing_params" : parent + "/preprocessing_params";
}

std::shared_ptr<const PreprocessingParams> parseAnnouncedParameters(const std::string& text, std::string* error)
{
  auto params = std::make_shared<PreprocessingParams>();
  std::string why;
  if (PreprocessingParams::parse(text, params.get(), &why))
    return params;
  *error = "Ignoring invalid preprocessing parameters '" + text + "': " + why;
  return nullptr;
}

namespace
{

// "0.10000000000000001" (as serialized, to round-trip) -> "0.1": the fewest digits that give the same
// double. Text that is not a number is returned as it is.
std::string readableValue(const std::string& text)
{
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end != text.c_str() + text.size())
    return text;
  if (std::fabs(value) < 1e15 && value == std::floor(value))
    return std::to_string(static_cast<long long>(value));  // 100, not the shortest form 1e+02
  for (int digits = 1; digits <= 17; ++digits)
  {
    std::ostringstream shorter;
    shorter.precision(digits);
    shorter << value;
    if (std::strtod(shorter.str().c_str(), nullptr) == value)
      return shorter.str();
  }
  return text;
}

}  // namespace

std::string preprocessingDifference(const PreprocessingParams& a, const PreprocessingParams& b)
{
  const auto fields = [](const std::string& text) {
    std::map<std::string, std::string> values;
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ';'))
    {
      const size_t equals = item.find('=');
      if (equals != std::string::npos)
        values[item.substr(0, equals)] = item.substr(equals + 1);
    }
    return values;
  };
  // Fields the normalization does not read make no difference (PreprocessingParams::canonical).
  const std::map<std::string, std::string> fields_a = fields(a.canonical().serialize());
  const std::map<std::string, std::string> fields_b = fields(b.canonical().serialize());
  std::string difference;
  for (const auto& field : fields_a)
  {
    const auto other = fields_b.find(field.first);
    const std::string value_b = other == fields_b.end() ? std::string("(none)") : other->second;
    if (value_b != field.second)
      difference += (difference.empty() ? "" : ", ") + field.first + ": " + readableValue(field.second) + " vs " +
                    readableValue(value_b);
  }
  for (const auto& field : fields_b)
    if (!fields_a.count(field.first))
      difference += (difference.empty() ? "" : ", ") + field.first + ": (none) vs " + readableValue(field.second);
  if (difference.empty() && a != b)
    difference = "'" + a.serialize() + "' vs '" + b.serialize() + "'";
  return difference;
}

BagFileHead bagFileHead(const std::string& path)
{
  static const std::string magic = "#ROSBAG V2.0\n";
  std::ifstream file(path, std::ios::binary);
  std::string head(magic.size(), '\0');
  file.read(&head[0], static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<size_t>(file.gcount()));  // 0 when the file does not open
  if (head.empty())
    return BagFileHead::kEmpty;
  if (head == magic)
    return BagFileHead::kRosbag2;
  if (magic.compare(0, head.size(), head) == 0)
    return BagFileHead::kCutInHeader;  // a start of the 2.0 header, cut ("#ROSBAG V2.0" without its newline)
  return head.compare(0, 9, "#ROSBAG V") == 0 ? BagFileHead::kOtherVersion : BagFileHead::kNotABag;
}

RouteMap readMap(const std::string& path, std::map<int, TaughtMotion>* motion)
{
  if (motion)
    motion->clear();
  checkMapFile(path);
  std::ifstream file(path, std::ios::binary);
  file.seekg(0, std::ios::end);
  const uint64_t size = static_cast<uint64_t>(file.tellg());
  file.seekg(13);  // past "#ROSBAG V2.0\n", checked above
  RecordScanner scanner(file, size);
  MapContents contents(path, size, motion);
  std::string compressed;  // the compression of the chunks, when they are compressed
  try
  {
    Record record;
    bool first = true;
    while (scanner.next(&record))
    {
      if (first && record.op != kOpBagHeader)
        throw CorruptMap("the first record is not the bag header");
      first = false;
      switch (record.op)
      {
        case kOpChunk:
        {
          const auto compression = record.fields.find("compression");
          if (compression == record.fields.end() || compression->second != "none")
          {
            // Said once the index's connections (after the chunks) tell whether this is a map at all:
            // "decompress it" sent a user to rewrite a camera bag given as the map.
            compressed = compression == record.fields.end() ? std::string("?") : compression->second;
            break;
          }
          if (fieldU32(record.fields, "size") != record.data.size())
            throw CorruptMap("a chunk's size field disagrees with its data");
          Cursor chunk(record.data.data(), record.data.size());
          while (chunk.left() > 0)
          {
            const uint32_t header_length = chunk.u32("a record header length");
            const std::string header(chunk.bytes(header_length, "a record header"), header_length);
            const uint32_t data_length = chunk.u32("a record data length");
            const Record inner = makeRecord(header, std::string(chunk.bytes(data_length, "a record"), data_length));
            if (inner.op == kOpConnection)
              contents.connection(inner);
            else if (inner.op == kOpMessageData)
              contents.message(inner);
            else
              throw CorruptMap("a chunk holds a record of op " + std::to_string(inner.op));
          }
          break;
        }
        case kOpConnection:
          contents.connection(record);
          break;
        case kOpMessageData:
          contents.message(record);
          break;
        case kOpBagHeader:
        case kOpIndexData:
        case kOpChunkInfo:
          break;
        default:
          throw CorruptMap("unknown record op " + std::to_string(record.op));
      }
    }
  }
  catch (const CorruptMap& e)
  {
    // `rosbag reindex` keeps the chunks before the damage: with no keyframe among them (a finished map is
    // one chunk), advising it sent a user round in a circle (the reindexed file held nothing, and said so).
    const size_t before = contents.keyframesRead();
    const std::string kept = std::to_string(before) + (before == 1 ? " keyframe" : " keyframes");
    std::string advice;
    if (endsWith(path, ".active"))
      advice = before > 0 ? "; a recording was interrupted: `rosbag reindex " + path + "` may recover the " + kept +
                                " it had flushed before the damage" :
                            "; a recording was interrupted before any keyframe lay complete in it: nothing to recover";
    else
      advice = "; was it copied only in part? Copy it again (a map the recorder finished is complete; an "
               "interrupted recording leaves MAP.active)" +
               (before > 0 ? ", or keep the " + kept + " before the damage with `rosbag reindex " + path + "`" :
                             std::string(": no keyframe lies complete before the damage, so `rosbag reindex` "
                                         "recovers none"));
    throw MapError("map file " + inQuotes(path) + " is truncated or corrupt at byte " +
                   std::to_string(scanner.offset()) + " of " + std::to_string(size) + ": " + e.what() + advice);
  }
  catch (const std::bad_alloc&)
  {
    throw MapError("map file " + inQuotes(path) + " is corrupt: a record claims an impossible size");
  }
  if (!compressed.empty())
  {
    const std::vector<std::string> topics = contents.topics();
    const auto is_map_topic = [](const std::string& topic) {
      return topic == kMapKeyframesTopic || topic == kMapPreprocessingTopic || topic == kMapInfoTopic;
    };
    if (!topics.empty() && std::none_of(topics.begin(), topics.end(), is_map_topic))
    {
      std::string listed;
      for (const std::string& topic : topics)
        listed += (listed.empty() ? "" : ", ") + topic;
      throw MapError(inQuotes(path) + " is a bag (" + compressed + "-compressed; topics " + listed +
                     "), not a map file: a map has the topics 'keyframes' and 'preprocessing' (written by the map "
                     "recorder, teach.launch, or `localize_offline --save-map`)");
    }
    throw MapError("map file " + inQuotes(path) + " has compressed chunks (" + compressed +
                   "); map files are written uncompressed: `rosbag decompress " + path + "`");
  }
  return contents.finish();
}

sensor_msgs::ImagePtr keyframeMessage(const cv::Mat& preprocessed, int64_t stamp_ns, const std::string& frame_id)
{
  if (preprocessed.type() != CV_8UC1 || preprocessed.empty())
    throw MapError("a keyframe must be a non-empty 8-bit single-channel image");
  sensor_msgs::ImagePtr msg = boost::make_shared<sensor_msgs::Image>();
  msg->header.stamp.fromNSec(static_cast<uint64_t>(std::max<int64_t>(stamp_ns, 0)));
  msg->header.frame_id = frame_id;
  msg->encoding = sensor_msgs::image_encodings::MONO8;
  msg->width = static_cast<uint32_t>(preprocessed.cols);
  msg->height = static_cast<uint32_t>(preprocessed.rows);
  msg->step = msg->width;
  msg->data.resize(static_cast<size_t>(msg->step) * msg->height);
  cv::Mat wrapped(preprocessed.rows, preprocessed.cols, CV_8UC1, &msg->data[0], msg->step);
  preprocessed.copyTo(wrapped);
  return msg;
}

std::map<int, TaughtMotion> readTaughtMotion(const std::string& path)
{
  std::map<int, TaughtMotion> motion;
  readMap(path, &motion);
  return motion;
}

void writeMap(const std::string& path, const RouteMap& map)
{
  MapWriter writer(path, map.params(), "writeMap");
  for (size_t i = 0; i < map.size(); ++i)
    writer.add(keyframeMessage(map.keyframeMat(i), map.stampNs(i)));
  writer.close();
}

namespace
{

// True for a bag that opens and has no keyframe messages (a writer's probe, or a recording stopped
// before its first flush); false for one that does not open (cut short while appending: it may hold
// keyframes that `rosbag reindex` recovers) or holds keyframes.
bool holdsNoKeyframes(const std::string& bag_path)
{
  try
  {
    rosbag::Bag bag(bag_path, rosbag::bagmode::Read);
    return rosbag::View(bag, rosbag::TopicQuery(kMapKeyframesTopic)).size() == 0;
  }
  catch (const std::exception&)
  {
    return false;
  }
}

}  // namespace

void requireAbsoluteMapPath(const std::string& path)
{
  if (path.empty() || path[0] == '/')
    return;
  char cwd[4096];
  const std::string here = ::getcwd(cwd, sizeof(cwd)) ? std::string(cwd) : std::string("(unknown)");
  throw MapError("map file " + inQuotes(path) + " is a relative path: this nodelet works in its manager's working "
                 "directory (" + here + ", ROS_HOME when roslaunch starts it), so it would be " +
                 inQuotes(here + "/" + path) + ", not where you started roslaunch. Give an absolute path " +
                 "(teach.launch and repeat.launch make a relative map:= absolute from where roslaunch was started)");
}

void checkMapTarget(const std::string& path)
{
  if (path.empty())
    throw MapError("no map file given (empty path)");
  const std::string active = path + ".active";
  struct stat info;
  if (fileExists(active, &info) && info.st_size > 0 && !holdsNoKeyframes(active))
    throw MapError(inQuotes(active) + " exists: a recording of " + inQuotes(path) +
                   " was interrupted while it was writing, and that file holds its keyframes. Recover it with "
                   "`rosbag reindex " + active + "` and rename it, or move it away, before recording again");
  if (fileExists(path, &info) && S_ISDIR(info.st_mode))
    throw MapError("map file " + inQuotes(path) + " is a directory; give the path of a file to write");
  // The folder must exist and take a new file: found only at the first keyframe, a missing or read-only
  // folder lost the whole teach while ~start said it was recording.
  const size_t slash = path.find_last_of('/');
  const std::string folder = slash == std::string::npos ? "." : slash == 0 ? "/" : path.substr(0, slash);
  if (!fileExists(folder, &info))
    throw MapError("the folder " + inQuotes(folder) + " of map file " + inQuotes(path) + " does not exist; create it");
  if (!S_ISDIR(info.st_mode))
    throw MapError(inQuotes(folder) + ", the folder of map file " + inQuotes(path) + ", is not a folder");
  const std::string probe = path + ".probe." + std::to_string(::getpid());
  const int fd = ::open(probe.c_str(), O_WRONLY | O_CREAT | O_EXCL, 0644);
  if (fd < 0)
    throw MapError("cannot write in the folder " + inQuotes(folder) + " of map file " + inQuotes(path) + ": " +
                   std::strerror(errno));
  ::close(fd);
  std::remove(probe.c_str());
}

namespace
{

/// rosbag::Bag's destructor closes the bag, and closing a bag whose write failed (a disk that filled up)
/// fails again and throws, from the destructor: std::terminate, which ends the whole nodelet manager. So
/// a bag being written lives on the heap (newBag), and one that failed is never destroyed: it is kept, for
/// the life of the process, in a list that is never freed (its buffers, at most about a chunk, once per
/// failed write; the room check before each flush stops a disk that stays full from failing again). Any
/// descriptor of this process still open for writing on `file` is pointed at /dev/null: a removed
/// half-written file then frees its disk space at once, not when the process ends, and whatever the bag's
/// stdio buffer might still write at exit goes nowhere. Returns true when nothing in this process can
/// write `file` any more (its descriptors pointed away, or none left: a bag that never opened it, or whose
/// close closed it); false when that cannot be known (no /proc) or the file is gone.
bool abandonBag(std::unique_ptr<rosbag::Bag>* bag, const std::string& file)
{
  static std::mutex mutex;
  static std::vector<rosbag::Bag*>* const abandoned = new std::vector<rosbag::Bag*>;  // never freed, see above
  if (*bag)
  {
    std::lock_guard<std::mutex> lock(mutex);
    abandoned->push_back(bag->release());
  }
  struct stat target;
  if (::stat(file.c_str(), &target) != 0)
    return false;
  DIR* fds = ::opendir("/proc/self/fd");
  if (!fds)
    return false;
  const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
  bool safe = true;
  while (const dirent* entry = ::readdir(fds))
  {
    char* end = nullptr;
    const long fd = std::strtol(entry->d_name, &end, 10);
    struct stat info;
    // Only descriptors open for writing: rosbag opens the bag it writes read-write, and a reader of the
    // same file elsewhere in the manager (a localizer loading it) keeps its own.
    if (end != entry->d_name && *end == '\0' && fd != ::dirfd(fds) && fd != null &&
        ::fstat(static_cast<int>(fd), &info) == 0 && info.st_dev == target.st_dev &&
        info.st_ino == target.st_ino && (::fcntl(static_cast<int>(fd), F_GETFL) & O_ACCMODE) != O_RDONLY)
      safe = null >= 0 && ::dup2(null, static_cast<int>(fd)) >= 0 && safe;
  }
  ::closedir(fds);
  if (null >= 0)
    ::close(null);
  return safe;
}

/// A rosbag::Bag on the heap (see abandonBag). Its constructor can throw too (rosbag 1.15 loads its
/// encryption plugin there, which needs free descriptors): MapError, before any file is touched.
std::unique_ptr<rosbag::Bag> newBag(const std::string& file)
{
  try
  {
    return std::unique_ptr<rosbag::Bag>(new rosbag::Bag);
  }
  catch (const std::exception& e)
  {
    throw MapError("cannot write map file " + inQuotes(file) + " (setting up rosbag failed: " + e.what() + ")");
  }
}

/// What rosbag's append changes in a bag besides adding chunks: it cuts the index off (connection and
/// chunk info records, from index_pos to the end) and rewrites the file header record. Saved before an
/// append, they put the file back byte for byte when the append fails.
struct BagEnds
{
  std::string head;  // "#ROSBAG V2.0\n" and the file header record
  uint64_t index_pos = 0;
  std::string index;  // from index_pos to the end of the file
  std::string chunks_start;  // the first KiB after the head: is the file still the one the ends are of?
};

/// The ends of the indexed bag at `path`; false when it is not one (then it cannot be put back).
bool readBagEnds(const std::string& path, BagEnds* ends)
{
  std::ifstream file(path, std::ios::binary);
  file.seekg(0, std::ios::end);
  const std::streamoff size = file.tellg();
  if (!file || size < 13)
    return false;
  file.seekg(13);  // past "#ROSBAG V2.0\n"
  RecordScanner scanner(file, static_cast<uint64_t>(size));
  uint64_t index_pos = 0;
  try
  {
    Record header;
    if (!scanner.next(&header) || header.op != kOpBagHeader)
      return false;
    const auto field = header.fields.find("index_pos");
    if (field == header.fields.end() || field->second.size() != 8)
      return false;
    Cursor cursor(field->second.data(), 8);  // little-endian 64 bits
    const uint64_t low = cursor.u32("index_pos");
    index_pos = static_cast<uint64_t>(cursor.u32("index_pos")) << 32 | low;
  }
  catch (const CorruptMap&)
  {
    return false;
  }
  const std::streamoff head_size = static_cast<std::streamoff>(scanner.offset());  // the header record's end
  if (index_pos < static_cast<uint64_t>(head_size) || index_pos > static_cast<uint64_t>(size))
    return false;
  ends->head.resize(static_cast<size_t>(head_size));
  ends->index.resize(static_cast<size_t>(static_cast<uint64_t>(size) - index_pos));
  ends->index_pos = index_pos;
  file.seekg(0);
  if (!file.read(&ends->head[0], head_size))
    return false;
  const uint64_t chunks_bytes = index_pos - static_cast<uint64_t>(head_size);
  ends->chunks_start.resize(static_cast<size_t>(std::min<uint64_t>(1024, chunks_bytes)));
  if (!file.read(&ends->chunks_start[0], static_cast<std::streamsize>(ends->chunks_start.size())))
    return false;
  file.seekg(static_cast<std::streamoff>(index_pos));
  return static_cast<bool>(file.read(&ends->index[0], static_cast<std::streamsize>(ends->index.size())));
}

/// Writes all of `bytes` at `offset` of `fd`; false with errno set when it cannot.
bool writeAllAt(int fd, const std::string& bytes, uint64_t offset)
{
  for (size_t done = 0; done < bytes.size();)
  {
    const ssize_t wrote = ::pwrite(fd, bytes.data() + done, bytes.size() - done, static_cast<off_t>(offset + done));
    if (wrote < 0 && errno == EINTR)
      continue;
    if (wrote <= 0)
      return false;
    done += static_cast<size_t>(wrote);
  }
  return true;
}

constexpr char kFlushedKeyframesGone[] = "it no longer holds the keyframes flushed before";

/// Puts the bag at `path`, whose append failed, back as it was before it: the chunks added cut off (which
/// frees what they took of the disk), then the index and the file header as they were. Only when it still
/// holds the chunks it had (an append whose open fell back to emptying the file holds none). Returns what
/// failed, or "".
std::string putBackBagEnds(const std::string& path, const BagEnds& ends)
{
  const int fd = ::open(path.c_str(), O_RDWR | O_CLOEXEC);
  if (fd < 0)
    return std::string("opening it: ") + std::strerror(errno);
  std::string chunks_start(ends.chunks_start.size(), '\0');
  struct stat info;
  std::string problem;
  if (::fstat(fd, &info) != 0 || static_cast<uint64_t>(info.st_size) < ends.index_pos ||
      ::pread(fd, &chunks_start[0], chunks_start.size(), static_cast<off_t>(ends.head.size())) !=
          static_cast<ssize_t>(chunks_start.size()) ||
      chunks_start != ends.chunks_start)
    problem = kFlushedKeyframesGone;
  else if (::ftruncate(fd, static_cast<off_t>(ends.index_pos)) != 0)
    problem = std::string("cutting off the chunks added: ") + std::strerror(errno);
  else if (!writeAllAt(fd, ends.index, ends.index_pos) || !writeAllAt(fd, ends.head, 0))
    problem = std::string("writing its index again: ") + std::strerror(errno);
  else if (::fsync(fd) != 0)
    problem = std::string("syncing it: ") + std::strerror(errno);
  ::close(fd);
  return problem;
}

}  // namespace

MapWriter::MapWriter(const std::string& path, const PreprocessingParams& params, const std::string& writer_info)
  : path_(path), params_(params), writer_info_(writer_info)
{
  if (path_.empty())
    throw MapError("no map file given (empty path)");
  const std::string invalid = params_.validate();
  if (!invalid.empty())
    throw MapError("cannot record a map with invalid preprocessing parameters: " + invalid);
  checkMapTarget(path_);
  // Can it be written? The probe is removed again: a writer killed before its first flush leaves nothing.
  std::unique_ptr<rosbag::Bag> probe = newBag(activePath());
  try
  {
    probe->open(activePath(), rosbag::bagmode::Write);
    probe->close();
  }
  catch (const std::exception& e)
  {
    abandonBag(&probe, activePath());
    std::remove(activePath().c_str());
    throw MapError("cannot write map file " + inQuotes(activePath()) + ": " + e.what());
  }
  std::remove(activePath().c_str());
}

MapWriter::~MapWriter()
{
  try
  {
    close();
  }
  catch (const std::exception& e)
  {
    ROS_ERROR_STREAM("Closing map " << inQuotes(path_) << " failed: " << e.what());
  }
}

void MapWriter::add(const sensor_msgs::ImageConstPtr& keyframe, const KeyframeMotionConstPtr& motion)
{
  if (closed_)
    throw MapError("map " + inQuotes(path_) + " is closed; no keyframes can be added");
  if (!keyframe)
    throw MapError("null keyframe");
  if (!isMono8(keyframe->encoding))
    throw MapError("keyframe has encoding '" + keyframe->encoding + "'; a map holds mono8 preprocessed images");
  if (static_cast<int>(keyframe->width) != params_.output_width ||
      static_cast<int>(keyframe->height) != params_.output_height ||
      keyframe->data.size() < static_cast<size_t>(keyframe->step) * keyframe->height ||
      keyframe->step < keyframe->width)
    throw MapError("keyframe is " + std::to_string(keyframe->width) + "x" + std::to_string(keyframe->height) +
                   " px (" + std::to_string(keyframe->data.size()) + " bytes), but the map's preprocessing makes " +
                   std::to_string(params_.output_width) + "x" + std::to_string(params_.output_height) + " px");
  pending_.push_back(keyframe);
  pending_motion_.push_back(motion);
}

std::string MapWriter::roomProblem(uint64_t size, uint64_t added) const
{
  // A write that fails part way leaves rosbag's file unindexed, and rosbag::Bag's destructor then throws
  // from close(), which ends the process: so the room is checked before a file is touched.
  struct rlimit limit;
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY && size + added > limit.rlim_cur)
    return "the file would pass the process's file size limit (" + std::to_string(limit.rlim_cur) +
           " bytes, ulimit -f)";
  const std::string folder = path_.substr(0, path_.find_last_of('/') + 1);
  struct statvfs disk;
  if (::statvfs(folder.empty() ? "." : folder.c_str(), &disk) == 0 &&
      static_cast<uint64_t>(disk.f_bavail) * disk.f_frsize < added)
    return std::to_string(static_cast<uint64_t>(disk.f_bavail) * disk.f_frsize / 1024) + " KiB free on its disk, " +
           std::to_string(added / 1024) + " KiB needed";
  return std::string();
}

void MapWriter::flush()
{
  if (pending_.empty())
    return;
  const std::string active = activePath();
  const bool first = written_ == 0;
  // What the file grows by, generously: each keyframe's bytes and records, and this flush's connection
  // records (rosbag's Append truncates the old index and writes it again after the new chunks, with one
  // new connection per topic, each with its message definition, a few KiB), and 64 KiB to spare.
  uint64_t needed = 64 * 1024 + 3 * 8 * 1024;
  for (const sensor_msgs::ImageConstPtr& keyframe : pending_)
    needed += keyframe->data.size() + 1024;
  struct stat info;
  const bool at_final_name = !first && fileExists(path_, &info);
  const uint64_t size = at_final_name ? static_cast<uint64_t>(info.st_size) : 0;
  if (!first && !at_final_name && fileExists(active, &info))
    throw MapError("map file " + inQuotes(path_) + " is missing: an earlier flush failed (said then); " +
                   inQuotes(active) + " holds what was flushed before (if it does not open, `rosbag reindex` may "
                   "recover it), " + std::to_string(pending_.size()) + " more are buffered");
  const std::string no_room = roomProblem(size, needed);
  if (!no_room.empty())
    throw MapError("no room to write " + std::to_string(pending_.size()) + " keyframes to " + inQuotes(path_) + ": " +
                   no_room + "; the map as flushed is kept and the keyframes stay buffered");
  std::unique_ptr<rosbag::Bag> bag = newBag(active);  // before any file is moved
  if (first && fileExists(path_, &info))
  {
    // A map from before under the same name: keep it under another name rather than overwrite it.
    const std::string kept = replacedMapPath(path_, info.st_mtime);
    if (std::rename(path_.c_str(), kept.c_str()) != 0)
      throw MapError("cannot move the existing file " + inQuotes(path_) + " aside to " + inQuotes(kept) +
                     " (it is never overwritten): " + std::strerror(errno));
    replaced_path_ = kept;
    ROS_WARN_STREAM("Map " << inQuotes(path_) << " existed; the new recording takes its name and the old map is "
                                                  "kept as "
                           << inQuotes(kept));
  }
  // The final name is moved aside while appending, so that it never names a bag being modified.
  BagEnds ends;  // to put the map back as flushed when the append fails
  const bool restorable = !first && readBagEnds(path_, &ends);
  if (!first && std::rename(path_.c_str(), active.c_str()) != 0)
    throw MapError("cannot move map file " + inQuotes(path_) + " to " + inQuotes(active) + ": " + std::strerror(errno));
  try
  {
    bag->open(active, first ? rosbag::bagmode::Write : rosbag::bagmode::Append);
    ros::Time bag_time = last_bag_time_;
    for (size_t i = 0; i < pending_.size(); ++i)
    {
      // Bag times strictly increase, so reading the bag in time order gives the map order even when
      // the source stamps jump back (a looping bag with sim time) or are zero.
      const ros::Time stamp = pending_[i]->header.stamp;
      bag_time = (stamp > bag_time && stamp >= ros::TIME_MIN) ? stamp : bag_time + ros::Duration(0, 1);
      if (bag_time < ros::TIME_MIN)
        bag_time = ros::TIME_MIN;
      if (first && i == 0)
      {
        std_msgs::String info;
        info.data = "format=" + std::to_string(kMapFormat) + ";writer=along_route_localization" +
                    (writer_info_.empty() ? std::string() : ";" + writer_info_);
        bag->write(kMapInfoTopic, bag_time, info);
        std_msgs::String preprocessing;
        preprocessing.data = params_.serialize();
        bag->write(kMapPreprocessingTopic, bag_time, preprocessing);
      }
      bag->write(kMapKeyframesTopic, bag_time, pending_[i]);
      if (pending_motion_[i])
      {
        KeyframeMotion motion = *pending_motion_[i];
        motion.keyframe = static_cast<uint32_t>(written_ + i);
        bag->write(kMapMotionTopic, bag_time, motion);
      }
    }
    bag->close();
    last_bag_time_ = bag_time;
  }
  catch (const std::exception& e)
  {
    // A disk that filled up since the room check, or an I/O error: the keyframes stay buffered, and the
    // map as flushed is put back under its final name.
    const std::string failed = "writing map file " + inQuotes(active) + " failed (" + e.what() + ")";
    const bool opened = bag->isOpen();  // false: its open failed before the file was opened, so untouched
    const bool alone = abandonBag(&bag, active);
    const std::string kept = "the keyframes stay buffered";
    if (first)
    {
      std::remove(active.c_str());
      throw MapError(failed + "; nothing was written yet, " + kept);
    }
    const std::string problem = !opened     ? std::string() :
                                !alone      ? std::string("the failed writer's descriptors could not be set aside") :
                                !restorable ? std::string("it was not an indexed bag before") :
                                              putBackBagEnds(active, ends);
    if (problem == kFlushedKeyframesGone)
      throw MapError(failed + "; " + inQuotes(active) + " " + problem + ": they are lost, " + kept);
    if (!problem.empty())
      throw MapError(failed + "; putting it back as flushed failed (" + problem + "): " + inQuotes(active) +
                     " holds the keyframes flushed so far (`rosbag reindex` may recover them), " + kept);
    if (std::rename(active.c_str(), path_.c_str()) != 0)
      throw MapError(failed + "; the map as flushed is back in " + inQuotes(active) + " but renaming it to " +
                     inQuotes(path_) + " failed (" + std::strerror(errno) + "), " + kept);
    throw MapError(failed + "; the map as flushed is kept and " + kept);
  }
  if (std::rename(active.c_str(), path_.c_str()) != 0)
    throw MapError("cannot rename " + inQuotes(active) + " to " + inQuotes(path_) + ": " + std::strerror(errno));
  written_ += pending_.size();
  pending_.clear();
  pending_motion_.clear();
  ++flushes_;
}

void MapWriter::writeOneConnectionPerTopic()
{
  const std::string active = activePath();
  struct stat info;
  const uint64_t size = fileExists(path_, &info) ? static_cast<uint64_t>(info.st_size) : 0;
  const std::string no_room = roomProblem(0, size + 64 * 1024);
  if (!no_room.empty())
  {
    ROS_WARN_STREAM("Map " << inQuotes(path_) << " is complete, but there is no room to write it again with one "
                                                 "connection per topic ("
                           << no_room << "); it keeps one per flush, which reads the same");
    return;
  }
  std::unique_ptr<rosbag::Bag> out;
  try
  {
    out = newBag(active);
    rosbag::Bag in(path_, rosbag::bagmode::Read);
    out->open(active, rosbag::bagmode::Write);
    // Bag times strictly increase (flush()), so time order is the map order. rosbag gives messages
    // written with equal connection headers on one topic one connection.
    for (const rosbag::MessageInstance& message : rosbag::View(in))
      out->write(message.getTopic(), message.getTime(), message, message.getConnectionHeader());
    out->close();
  }
  catch (const std::exception& e)
  {
    abandonBag(&out, active);
    std::remove(active.c_str());
    ROS_WARN_STREAM("Map " << inQuotes(path_) << " is complete, but writing it with one connection per topic failed ("
                           << e.what() << "); it keeps one per flush, which reads the same");
    return;
  }
  if (std::rename(active.c_str(), path_.c_str()) != 0)
  {
    ROS_WARN_STREAM("Map " << inQuotes(path_) << " is complete, but renaming " << inQuotes(active)
                           << " over it failed (" << std::strerror(errno) << "); it keeps one connection per flush");
    std::remove(active.c_str());
  }
}

void MapWriter::close()
{
  if (closed_)
    return;
  closed_ = true;
  flush();
  if (written_ == 0)
    std::remove(activePath().c_str());  // nothing recorded: leave no file behind
  else if (flushes_ > 1)
    writeOneConnectionPerTopic();
}

}  // namespace along_route_localization
