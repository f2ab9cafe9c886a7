// The route map file: a rosbag holding the keyframes and the preprocessing parameters that made them.
// Shared by the map recorder and localizer nodelets and the offline tools.
//
// Layout (format 1):
//   topic "keyframes"      sensor_msgs/Image, mono8, map order; header.stamp = the keyframe's source stamp
//   topic "preprocessing"  std_msgs/String, PreprocessingParams::serialize() (exactly one message)
//   topic "info"           std_msgs/String, "format=1;..." (what wrote the map)
//   topic "motion"         along_route_localization/KeyframeMotion, optional: the taught motion, one message
//                          per keyframe, each right after its keyframe (maps without it load all the same)
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_MAP_IO_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_MAP_IO_H

#include <cstdint>
#include <ctime>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <ros/time.h>
#include <sensor_msgs/Image.h>

#include "along_route_localization/KeyframeMotion.h"
#include "along_route_localization/preprocessing.h"
#include "along_route_localization/route_follower.h"
#include "along_route_localization/route_map.h"

namespace along_route_localization
{

constexpr char kMapKeyframesTopic[] = "keyframes";
constexpr char kMapPreprocessingTopic[] = "preprocessing";
constexpr char kMapInfoTopic[] = "info";
constexpr char kMapMotionTopic[] = "motion";
constexpr int kMapFormat = 1;

/// The preprocessor announces the parameters that make its images on a latched std_msgs/String
/// (PreprocessingParams::serialize()) next to the image topic, as camera_info sits next to image:
/// `<namespace of the resolved image topic>/preprocessing_params`. It publishes a new value right
/// before the first image made with it, so a subscriber in the same process always knows what made
/// the image it receives. The map recorder stores the value in the map; the localizer refuses a map
/// whose parameters differ.
std::string preprocessingParamsTopic(const std::string& resolved_image_topic);

/// The parameters a preprocessor announced on that topic (PreprocessingParams::serialize() text), or
/// nullptr with *error the sentence to log: "Ignoring invalid preprocessing parameters '...': why".
std::shared_ptr<const PreprocessingParams> parseAnnouncedParameters(const std::string& text, std::string* error);

/// "output_width: 64 vs 32, sky_fraction: 0 vs 0.25" -- the fields whose serialized values differ.
std::string preprocessingDifference(const PreprocessingParams& a, const PreprocessingParams& b);

/// What a file's first bytes say it is, for errors that name the problem (rosbag's own, such as "wanted
/// 4 bytes, read 0 bytes", do not): empty, a rosbag 2.0, a rosbag of another version, cut short inside the
/// 13-byte bag header, or something else. An unreadable file counts as empty.
enum class BagFileHead
{
  kEmpty,
  kRosbag2,
  kOtherVersion,
  kCutInHeader,
  kNotABag
};
BagFileHead bagFileHead(const std::string& path);

/// Reads a map file. Throws MapError with a sentence naming the file and what is wrong: missing,
/// empty, not a bag, truncated or corrupt (with the `rosbag reindex` hint for an interrupted write),
/// no or unparsable preprocessing parameters, no keyframes, keyframes of another encoding or size
/// than the parameters say. With `motion`, also the taught motion (topic "motion") by keyframe index
/// (empty for a map recorded without it; MapError when the topic has another type or a value is not finite).
RouteMap readMap(const std::string& path, std::map<int, TaughtMotion>* motion = nullptr);

/// The taught motion a map file holds (readMap with `motion`), by keyframe index; empty for a map recorded
/// without it. Throws MapError as readMap does.
std::map<int, TaughtMotion> readTaughtMotion(const std::string& path);

/// Writes a whole map at once (through MapWriter). Throws MapError.
void writeMap(const std::string& path, const RouteMap& map);

/// A keyframe message (mono8, a copy of `preprocessed`) as the map file stores it.
sensor_msgs::ImagePtr keyframeMessage(const cv::Mat& preprocessed, int64_t stamp_ns,
                                      const std::string& frame_id = std::string());

/// The name under which a map file that a new recording replaces is kept: "route.bag" last modified
/// 2026-11-24 10:03:11 -> "route.replaced-2026-11-24-10-03-11.bag", with "-2", "-3", ... when that name is
/// taken too. Nothing is ever overwritten.
std::string replacedMapPath(const std::string& path, time_t modified);

/// Throws MapError when a map cannot be recorded to `path`: empty, a directory, or a `<path>.active`
/// left by an interrupted recording that may hold its keyframes (one that does not open as a bag, or
/// holds keyframe messages; an empty bag is no loss and is reused).
void checkMapTarget(const std::string& path);

/// Throws MapError when `path` is relative. For the nodelets: a nodelet works in its manager's working
/// directory (ROS_HOME, ~/.ros, for nodes that roslaunch starts), not where the user started roslaunch,
/// so a relative path would name a file where nobody looks. The sentence names both places.
/// teach.launch and repeat.launch make a relative map:= absolute first, from where roslaunch was started.
void requireAbsoluteMapPath(const std::string& path);

/// Writes a map as it is recorded. Not thread-safe: one thread (the recorder's writer thread) owns it.
///
/// Keyframes added are buffered until flush(). Each flush appends them to `<path>.active` and renames
/// that to `<path>`, so the final name only ever holds a complete, indexed map of everything flushed so
/// far; `<path>.active` exists only while a flush is writing (if the process dies there, `rosbag
/// reindex <path>.active` recovers it). A map file left from before keeps its name until the first
/// keyframe of the new recording is flushed; then it is renamed to replacedPath()
/// (`<stem>.replaced-<its modification time>.bag`), never overwritten.
///
/// rosbag's Append mode starts new connections, so after n flushes the map holds n connections per
/// topic (each with its message definition: a short flush period makes the file several times larger).
/// close() writes it once more in one go, with one connection per topic, as `rosbag record` does.
class MapWriter
{
public:
  /// Checks that `<path>.active` can be written (creates and removes it). Throws MapError, also when a
  /// `<path>.active` that may hold keyframes exists (an interrupted recording's: it is not overwritten).
  MapWriter(const std::string& path, const PreprocessingParams& params,
            const std::string& writer_info = std::string());
  /// close(); errors are logged, not thrown.
  virtual ~MapWriter();

  MapWriter(const MapWriter&) = delete;
  MapWriter& operator=(const MapWriter&) = delete;

  /// Buffers a keyframe (held by pointer, not copied) and, when given, the motion taught there (written
  /// with the keyframe's map index, whatever its `keyframe` field says). Throws MapError unless the
  /// keyframe is mono8 (or 8UC1) of the parameters' output size.
  void add(const sensor_msgs::ImageConstPtr& keyframe, const KeyframeMotionConstPtr& motion = KeyframeMotionConstPtr());

  /// Writes the buffered keyframes; afterwards `<path>` is a complete map. No-op when nothing is
  /// buffered. Throws MapError (the keyframes stay buffered, so a later flush may retry), also, before the
  /// file is touched, when the disk or the file size limit leaves no room for them; when the write itself
  /// fails (a disk that filled up meanwhile), `<path>` is put back byte for byte as it was flushed.
  void flush();

  /// flush() and stop accepting keyframes; a map written by more than one flush is then written again
  /// with one connection per topic (if that fails, the map as flushed stays, complete, and a warning
  /// is logged). Idempotent. Throws MapError.
  void close();

  const std::string& path() const { return path_; }
  std::string activePath() const { return path_ + ".active"; }
  const PreprocessingParams& params() const { return params_; }
  /// Keyframes added so far / written to `<path>` so far.
  size_t added() const { return written_ + pending_.size(); }
  size_t written() const { return written_; }
  bool closed() const { return closed_; }
  /// Where the map that was at path() before this recording is kept; empty when there was none.
  const std::string& replacedPath() const { return replaced_path_; }

protected:
  /// Why `added` bytes cannot be written to a file of `size` bytes next to path() (the file size limit, the
  /// disk's free space), or "" when they can. Virtual for the tests: a disk can fill up between this check
  /// and the write, and a test writer that skips it shows what happens then.
  virtual std::string roomProblem(uint64_t size, uint64_t added) const;

private:
  /// Writes the map at path() again with one connection per topic (see the class comment).
  void writeOneConnectionPerTopic();

  std::string path_;
  PreprocessingParams params_;
  std::string writer_info_;
  std::vector<sensor_msgs::ImageConstPtr> pending_;
  std::vector<KeyframeMotionConstPtr> pending_motion_;  // one per pending keyframe, null where none
  size_t written_ = 0;
  int flushes_ = 0;  // that wrote keyframes
  ros::Time last_bag_time_;
  bool closed_ = false;
  std::string replaced_path_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_MAP_IO_H
