// The map file (src/glue/map_io.*): round trip, the streaming writer's flush/rename contract, a writer
// killed mid-recording, and a clear MapError for every kind of bad file.
#include <gtest/gtest.h>

#include <signal.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <string>
#include <vector>

#include <csignal>
#include <dirent.h>
#include <sys/resource.h>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/image_encodings.h>
#include <std_msgs/String.h>

#include "glue/map_io.h"

namespace along_route_localization
{
namespace
{

/// The MapError message of call() (a flush, a close, a read), or "" when it went through.
template <typename Call>
std::string mapErrorOf(Call call)
{
  try
  {
    call();
  }
  catch (const MapError& e)
  {
    return e.what();
  }
  return "";
}

class MapIoTest : public ::testing::Test
{
protected:
  void SetUp() override
  {
    char pattern[] = "/tmp/along_route_map_io_XXXXXX";
    ASSERT_NE(mkdtemp(pattern), nullptr);
    dir_ = pattern;
  }
  void TearDown() override
  {
    const std::string command = "rm -rf '" + dir_ + "'";
    ASSERT_EQ(std::system(command.c_str()), 0);
  }
  std::string path(const std::string& name) const { return dir_ + "/" + name; }

  static cv::Mat randomKeyframe(cv::RNG& rng, int width = 64, int height = 32)
  {
    cv::Mat image(height, width, CV_8UC1);
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    return image;
  }

  static bool exists(const std::string& file)
  {
    struct stat info;
    return ::stat(file.c_str(), &info) == 0;
  }

  static off_t fileSize(const std::string& file)
  {
    struct stat info;
    return ::stat(file.c_str(), &info) == 0 ? info.st_size : -1;
  }

  static std::string readAll(const std::string& file)
  {
    std::ifstream in(file, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }

  static void writeAll(const std::string& file, const std::string& bytes)
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  /// The MapError message of readMap(file), or "" when it reads.
  static std::string readError(const std::string& file)
  {
    return mapErrorOf([&] { readMap(file); });
  }

  std::string writeTestMap(const std::string& name, int keyframes, uint64_t seed = 42)
  {
    cv::RNG rng(seed);
    RouteMap map{ PreprocessingParams() };
    for (int k = 0; k < keyframes; ++k)
      map.addKeyframe(randomKeyframe(rng), 1000000000LL * (k + 1) + 7);
    writeMap(path(name), map);
    return path(name);
  }

  std::string dir_;
};

std_msgs::String text(const std::string& data)
{
  std_msgs::String msg;
  msg.data = data;
  return msg;
}

TEST_F(MapIoTest, RoundTripKeepsBytesStampsAndParameters)
{
  PreprocessingParams params;
  params.normalization = NormalizationMethod::kDivisive;
  params.filter_window = 9;
  params.sky_fraction = 0.25;
  cv::RNG rng(7);
  RouteMap map(params);
  for (int k = 0; k < 5; ++k)
    map.addKeyframe(randomKeyframe(rng), 1600000000LL * 1000000000LL + k * 100000000LL);
  writeMap(path("map.bag"), map);

  const RouteMap read = readMap(path("map.bag"));
  EXPECT_TRUE(read.params() == params);
  ASSERT_EQ(read.size(), 5u);
  for (size_t k = 0; k < 5; ++k)
  {
    EXPECT_EQ(read.stampNs(k), map.stampNs(k));
    EXPECT_EQ(0, std::memcmp(read.keyframe(k), map.keyframe(k), map.keyframeBytes())) << "keyframe " << k;
  }
  EXPECT_FALSE(exists(path("map.bag.active")));
}

TEST_F(MapIoTest, EachFlushLeavesACompleteMapUnderTheFinalName)
{
  const std::string file = writeTestMap("map.bag", 3);  // an older map under the same name
  cv::RNG rng(1);
  MapWriter writer(file, PreprocessingParams());
  EXPECT_FALSE(exists(file + ".active")) << "the writability probe is removed";
  EXPECT_EQ(readMap(file).size(), 3u) << "the old map stays until the first keyframe is flushed";

  for (int k = 0; k < 4; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
  EXPECT_EQ(readMap(file).size(), 3u) << "nothing is written before flush()";
  writer.flush();
  EXPECT_EQ(readMap(file).size(), 4u);
  EXPECT_FALSE(exists(file + ".active"));
  ASSERT_EQ(writer.replacedPath().rfind(path("map.replaced-"), 0), 0u) << writer.replacedPath();
  EXPECT_EQ(readMap(writer.replacedPath()).size(), 3u) << "the older map is kept, not overwritten";

  for (int k = 0; k < 2; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 20 + k));
  writer.flush();
  const RouteMap appended = readMap(file);
  ASSERT_EQ(appended.size(), 6u);
  EXPECT_EQ(appended.stampNs(3), 13);
  EXPECT_EQ(appended.stampNs(4), 20);
  writer.close();
  EXPECT_EQ(writer.written(), 6u);
  EXPECT_EQ(readMap(file).size(), 6u);
  EXPECT_FALSE(exists(file + ".active"));
  EXPECT_THROW(writer.add(keyframeMessage(randomKeyframe(rng), 30)), MapError);
}

/// Sets the process's file size limit for its lifetime (SIGXFSZ ignored: EFBIG instead of the signal).
class FileSizeLimit
{
public:
  explicit FileSizeLimit(off_t bytes)
  {
    getrlimit(RLIMIT_FSIZE, &old_limit_);
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);
    struct rlimit limit = old_limit_;
    limit.rlim_cur = static_cast<rlim_t>(bytes);
    ok_ = setrlimit(RLIMIT_FSIZE, &limit) == 0;
  }
  ~FileSizeLimit()
  {
    setrlimit(RLIMIT_FSIZE, &old_limit_);
    std::signal(SIGXFSZ, old_handler_);
  }
  bool ok() const { return ok_; }

private:
  struct rlimit old_limit_;
  sighandler_t old_handler_;
  bool ok_ = false;
};


// A flush without room (here the process's file size limit; a full disk is checked the same way) must not
// lose the map flushed before: the final name keeps it, the keyframes stay buffered, and a flush once there
// is room again writes them all. Before, rosbag failed part way through the append, its Bag's destructor
// threw from close() and the process ended (std::terminate: the recorder's whole nodelet manager).
TEST_F(MapIoTest, AFlushWithoutRoomKeepsTheMapAndALaterFlushWritesEverything)
{
  const std::string file = path("map.bag");
  cv::RNG rng(3);
  MapWriter writer(file, PreprocessingParams());
  for (int k = 0; k < 4; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
  writer.flush();
  ASSERT_EQ(readMap(file).size(), 4u);
  const off_t flushed = fileSize(file);

  std::string error;
  {
    // Each keyframe is counted as its 2048 bytes + 1 KiB, the flush as 64 + 24 KiB more: room for 1 keyframe
    // (91 KiB) under 100 KiB, not for 40 (208 KiB).
    FileSizeLimit limit(flushed + 100 * 1024);
    ASSERT_TRUE(limit.ok());
    writer.add(keyframeMessage(randomKeyframe(rng), 19));
    const std::string fits = mapErrorOf([&] { writer.flush(); });
    EXPECT_EQ("", fits) << "a flush that fits was refused: " << fits;
    for (int k = 0; k < 40; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 20 + k));
    error = mapErrorOf([&] { writer.flush(); });
  }
  EXPECT_NE("", error) << "a flush that could not write did not say so";
  std::printf("the failed flush said: %s\n", error.c_str());
  EXPECT_TRUE(exists(file)) << "the final name lost the map flushed before";
  EXPECT_EQ("", readError(file));
  EXPECT_EQ(5u, readMap(file).size());
  EXPECT_EQ(5u, writer.written());
  EXPECT_EQ(45u, writer.added());

  writer.flush();  // room again
  EXPECT_EQ(45u, readMap(file).size());
  writer.close();
  EXPECT_EQ(45u, readMap(file).size());
  EXPECT_FALSE(exists(file + ".active"));
}

// A disk can fill up between the room check and the write (another process writing to it). A writer whose
// check never finds a problem shows what happens then; the process's file size limit makes the write fail
// (EFBIG, as ENOSPC on a full disk).
class BlindMapWriter : public MapWriter
{
public:
  using MapWriter::MapWriter;

protected:
  std::string roomProblem(uint64_t /*size*/, uint64_t /*added*/) const override { return ""; }
};

/// How many of this process's descriptors refer to `file` (also once it is removed: "<file> (deleted)").
int descriptorsOn(const std::string& file)
{
  int count = 0;
  DIR* fds = opendir("/proc/self/fd");
  if (!fds)
    return -1;
  while (const dirent* entry = readdir(fds))
  {
    char target[4096];
    const std::string link = std::string("/proc/self/fd/") + entry->d_name;
    const ssize_t length = readlink(link.c_str(), target, sizeof(target) - 1);
    if (length > 0 && std::string(target, static_cast<size_t>(length)).rfind(file, 0) == 0)
      ++count;
  }
  closedir(fds);
  return count;
}


// Before, rosbag failed part way through the append, the Bag's destructor threw again from close() and
// the process ended (std::terminate: the recorder's whole nodelet manager), leaving the map unindexed under
// `.active`. Now the map file is put back byte for byte as it was flushed.
TEST_F(MapIoTest, ADiskThatFillsDuringAnAppendKeepsTheMapAsFlushedByteForByte)
{
  const std::string file = path("map.bag");
  cv::RNG rng(5);
  BlindMapWriter writer(file, PreprocessingParams());
  for (int k = 0; k < 4; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
  writer.flush();
  for (int k = 0; k < 3; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 20 + k));
  writer.flush();  // two flushes: the index holds two connections per topic, all of it to be put back
  const std::string flushed = readAll(file);
  ASSERT_EQ(7u, readMap(file).size());

  for (int k = 0; k < 40; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 30 + k));
  std::string error;
  std::ifstream reader(file, std::ios::binary);  // the map open for reading elsewhere (a localizer loading it)
  {
    // Room for about 10 of the 40 keyframes (2 KiB each): the append fails inside its chunk.
    FileSizeLimit limit(static_cast<off_t>(flushed.size()) + 20 * 1024);
    ASSERT_TRUE(limit.ok());
    error = mapErrorOf([&] { writer.flush(); });
  }
  EXPECT_TRUE(std::string(std::istreambuf_iterator<char>(reader), std::istreambuf_iterator<char>()) == flushed)
      << "a reader of the map file lost it";
  reader.close();
  std::fflush(nullptr);  // as exit() does: what the failed writer's stdio buffer holds must not reach the map
  std::printf("the failed flush said: %s\n", error.c_str());
  EXPECT_NE(std::string::npos, error.find("writing map file")) << error;
  EXPECT_NE(std::string::npos, error.find("stay buffered")) << error;
  EXPECT_FALSE(exists(file + ".active"));
  EXPECT_TRUE(readAll(file) == flushed) << "the map file is not as it was flushed (" << fileSize(file)
                                        << " bytes, " << flushed.size() << " before)";
  EXPECT_EQ("", readError(file));
  {
    rosbag::Bag bag(file, rosbag::bagmode::Read);  // rosbag's own reader: the index is whole again
    EXPECT_EQ(7u, rosbag::View(bag, rosbag::TopicQuery(kMapKeyframesTopic)).size());
  }
  EXPECT_EQ(7u, writer.written());
  EXPECT_EQ(47u, writer.added());
  EXPECT_EQ(0, descriptorsOn(file)) << "the failed writer still holds the map file open";

  writer.flush();  // room again: nothing was lost
  EXPECT_EQ(47u, readMap(file).size());
  writer.close();
  const RouteMap closed = readMap(file);
  ASSERT_EQ(47u, closed.size());
  EXPECT_EQ(30, closed.stampNs(7));
  EXPECT_EQ(69, closed.stampNs(46));
  EXPECT_FALSE(exists(file + ".active"));
}

TEST_F(MapIoTest, ADiskThatFillsDuringTheFirstFlushLeavesNoFileAndLosesNoKeyframe)
{
  const std::string file = path("map.bag");
  cv::RNG rng(6);
  BlindMapWriter writer(file, PreprocessingParams());
  for (int k = 0; k < 40; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
  std::string error;
  {
    FileSizeLimit limit(30 * 1024);
    ASSERT_TRUE(limit.ok());
    error = mapErrorOf([&] { writer.flush(); });
  }
  EXPECT_NE(std::string::npos, error.find("writing map file")) << error;
  EXPECT_FALSE(exists(file));
  EXPECT_FALSE(exists(file + ".active")) << "a half-written first flush is left behind";
  EXPECT_EQ(0, descriptorsOn(file)) << "a descriptor holds the removed half-written file's disk space";
  EXPECT_EQ(0u, writer.written());
  writer.close();
  EXPECT_EQ(40u, readMap(file).size());
}

// Out of descriptors, rosbag cannot even set up a bag (1.15 loads its encryption plugin in Bag's constructor,
// which threw out of flush() after the map file had been moved aside, leaving it only under `.active`).
TEST_F(MapIoTest, AFlushWithoutFreeDescriptorsKeepsTheMapUnderItsName)
{
#if defined(__SANITIZE_ADDRESS__)
  // UBSan's check of the exception's type opens a pipe to read memory, and with no descriptor it reports an
  // invalid vptr; the plain build runs this test (the sanitizers stage runs the others).
  GTEST_SKIP() << "needs a process that can run without free descriptors; not under ASan + UBSan";
#endif
  const std::string file = path("map.bag");
  cv::RNG rng(9);
  MapWriter writer(file, PreprocessingParams());
  for (int k = 0; k < 4; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
  writer.flush();
  const std::string flushed = readAll(file);
  for (int k = 0; k < 3; ++k)
    writer.add(keyframeMessage(randomKeyframe(rng), 20 + k));
  struct rlimit old_limit;
  ASSERT_EQ(0, getrlimit(RLIMIT_NOFILE, &old_limit));
  struct rlimit limit = old_limit;
  limit.rlim_cur = 0;  // no new descriptor; those open stay usable
  ASSERT_EQ(0, setrlimit(RLIMIT_NOFILE, &limit));
  const std::string error = mapErrorOf([&] { writer.flush(); });
  ASSERT_EQ(0, setrlimit(RLIMIT_NOFILE, &old_limit));
  std::printf("the failed flush said: %s\n", error.c_str());
  EXPECT_NE("", error);
  EXPECT_TRUE(readAll(file) == flushed) << "the map file is not as it was flushed";
  EXPECT_FALSE(exists(file + ".active"));
  writer.flush();
  EXPECT_EQ(7u, readMap(file).size());
}

TEST_F(MapIoTest, AWriterThatCannotProbeItsFileSaysSoAndLeavesNothing)
{
  const std::string file = path("map.bag");
  std::string error;
  {
    FileSizeLimit limit(100);  // not even rosbag's 4 KiB file header fits
    ASSERT_TRUE(limit.ok());
    try
    {
      BlindMapWriter writer(file, PreprocessingParams());
    }
    catch (const MapError& e)
    {
      error = e.what();
    }
  }
  std::fflush(nullptr);
  EXPECT_NE(std::string::npos, error.find("cannot write map file")) << error;
  EXPECT_FALSE(exists(file + ".active"));
  EXPECT_EQ(0, descriptorsOn(file));
}

// After a flush that could not put the map back (here: its final name moved away by hand), each later flush
// says where the keyframes flushed before are instead of failing to move a file that is not there.
TEST_F(MapIoTest, AMapThatCouldNotBePutBackIsNamedAtEachLaterFlush)
{
  const std::string file = path("map.bag");
  cv::RNG rng(10);
  MapWriter writer(file, PreprocessingParams());
  writer.add(keyframeMessage(randomKeyframe(rng), 10));
  writer.flush();
  ASSERT_EQ(0, std::rename(file.c_str(), (file + ".active").c_str()));
  writer.add(keyframeMessage(randomKeyframe(rng), 11));
  const std::string error = mapErrorOf([&] { writer.flush(); });
  EXPECT_NE(std::string::npos, error.find("is missing: an earlier flush failed")) << error;
  EXPECT_NE(std::string::npos, error.find("holds what was flushed before")) << error;
  EXPECT_NE(std::string::npos, error.find("1 more are buffered")) << error;
  EXPECT_EQ(1u, readMap(file + ".active").size());
  ASSERT_EQ(0, std::rename((file + ".active").c_str(), file.c_str()));
  writer.close();
  EXPECT_EQ(2u, readMap(file).size());
}

// close() writes a map flushed more than once again, with one connection per topic, into `.active`; when
// the disk fills during that, the map as flushed stays and nothing is left behind.
TEST_F(MapIoTest, ADiskThatFillsWhileClosingKeepsTheMapAsFlushed)
{
  const std::string file = path("map.bag");
  cv::RNG rng(8);
  BlindMapWriter writer(file, PreprocessingParams());
  for (int flush = 0; flush < 3; ++flush)
  {
    for (int k = 0; k < 20; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 100 * flush + k));
    writer.flush();
  }
  const std::string flushed = readAll(file);
  std::string error;
  {
    FileSizeLimit limit(static_cast<off_t>(flushed.size()) / 2);  // the copy cannot fit
    ASSERT_TRUE(limit.ok());
    error = mapErrorOf([&] { writer.close(); });
  }
  std::fflush(nullptr);  // as exit() does
  EXPECT_EQ("", error) << "closing a complete map failed";
  EXPECT_TRUE(writer.closed());
  EXPECT_FALSE(exists(file + ".active"));
  EXPECT_TRUE(readAll(file) == flushed) << "the map file is not as it was flushed";
  EXPECT_EQ(60u, readMap(file).size());
  EXPECT_EQ(0, descriptorsOn(file)) << "a descriptor holds the removed half-written copy's disk space";
}

// Issue 33: each flush appended new connections (60 for 599 keyframes; a file 2.5x larger with a short
// flush period). A closed map holds one connection per topic, as `rosbag record` writes.
TEST_F(MapIoTest, AClosedMapHoldsOneConnectionPerTopic)
{
  const std::string file = path("map.bag");
  cv::RNG rng(4);
  MapWriter writer(file, PreprocessingParams());
  std::vector<cv::Mat> keyframes;
  for (int flush = 0; flush < 5; ++flush)
  {
    for (int k = 0; k < 3; ++k)
    {
      keyframes.push_back(randomKeyframe(rng));
      writer.add(keyframeMessage(keyframes.back(), 100 + 10 * flush + k));
    }
    writer.flush();
  }
  const auto connectionsPerTopic = [&file]() {
    rosbag::Bag bag(file, rosbag::bagmode::Read);
    rosbag::View view(bag);
    std::map<std::string, int> count;
    for (const rosbag::ConnectionInfo* connection : view.getConnections())
      ++count[connection->topic];
    return count;
  };
  EXPECT_EQ(connectionsPerTopic()[kMapKeyframesTopic], 5) << "while recording: one per flush (rosbag's Append)";
  const off_t flushed_size = fileSize(file);
  writer.close();
  const std::map<std::string, int> closed = connectionsPerTopic();
  EXPECT_EQ(closed, (std::map<std::string, int>{ { kMapInfoTopic, 1 }, { kMapKeyframesTopic, 1 },
                                                 { kMapPreprocessingTopic, 1 } }));
  EXPECT_LT(fileSize(file), flushed_size) << "four message definitions of sensor_msgs/Image fewer";
  EXPECT_FALSE(exists(file + ".active"));
  const RouteMap map = readMap(file);
  ASSERT_EQ(map.size(), keyframes.size());
  for (size_t k = 0; k < keyframes.size(); ++k)
  {
    EXPECT_EQ(map.stampNs(k), static_cast<int64_t>(100 + 10 * (k / 3) + k % 3));
    EXPECT_EQ(cv::norm(map.keyframeMat(k), keyframes[k], cv::NORM_L1), 0.0) << k;
  }
}

// Issue 33: a relative map:= was written under $ROS_HOME (the manager's working directory).
TEST(MapIo, TheNodeletsRefuseARelativeMapPathNamingWhereItWouldBe)
{
  EXPECT_NO_THROW(requireAbsoluteMapPath("/tmp/route.bag"));
  EXPECT_NO_THROW(requireAbsoluteMapPath(""));  // "no map", said elsewhere
  char cwd[4096];
  ASSERT_NE(::getcwd(cwd, sizeof(cwd)), nullptr);
  try
  {
    requireAbsoluteMapPath("route.bag");
    FAIL() << "a relative path was accepted";
  }
  catch (const MapError& e)
  {
    const std::string what = e.what();
    EXPECT_NE(what.find("'route.bag' is a relative path"), std::string::npos) << what;
    EXPECT_NE(what.find("'" + std::string(cwd) + "/route.bag'"), std::string::npos) << what;
  }
}

TEST_F(MapIoTest, EveryMapThatWasThereIsKeptUnderItsOwnName)
{
  const std::string file = writeTestMap("route.bag", 3);
  cv::RNG rng(2);
  std::vector<std::string> kept;
  for (int recording = 0; recording < 2; ++recording)
  {
    MapWriter writer(file, PreprocessingParams());
    EXPECT_TRUE(writer.replacedPath().empty()) << "nothing is moved before the first keyframe is written";
    for (int k = 0; k < 4 + recording; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
    writer.close();
    kept.push_back(writer.replacedPath());
  }
  // Both recordings may happen within one second of the maps they replace: the names still differ.
  ASSERT_NE(kept[0], kept[1]);
  EXPECT_EQ(readMap(kept[0]).size(), 3u);
  EXPECT_EQ(readMap(kept[1]).size(), 4u);
  EXPECT_EQ(readMap(file).size(), 5u);
  for (const std::string& name : kept)
    EXPECT_EQ(name.substr(name.size() - 4), ".bag") << name << " is still a bag by its name";
}

TEST_F(MapIoTest, AnInterruptedRecordingIsNotOverwritten)
{
  const std::string file = path("route.bag");
  const std::string interrupted = "#ROSBAG V2.0\nkeyframes of a recording killed while appending";
  writeAll(file + ".active", interrupted);
  try
  {
    MapWriter writer(file, PreprocessingParams());
    ADD_FAILURE() << "a writer started over " << file << ".active";
  }
  catch (const MapError& e)
  {
    EXPECT_NE(std::string(e.what()).find("interrupted"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("rosbag reindex " + file + ".active"), std::string::npos) << e.what();
  }
  EXPECT_EQ(readAll(file + ".active"), interrupted);
  EXPECT_THROW(checkMapTarget(file), MapError);

  // One that is a bag with keyframes (killed between appending and renaming) is refused too.
  writeTestMap("route.bag.active", 2);
  EXPECT_THROW(checkMapTarget(file), MapError);

  // Empty files and bags without keyframes hold nothing and are reused.
  writeAll(file + ".active", "");
  EXPECT_NO_THROW(checkMapTarget(file));
  {
    rosbag::Bag header_only(file + ".active", rosbag::bagmode::Write);
  }
  EXPECT_NO_THROW(checkMapTarget(file));
  EXPECT_NO_THROW(MapWriter(file, PreprocessingParams()));
  EXPECT_THROW(checkMapTarget(dir_), MapError) << "a directory";

  // A recorder killed before its first flush leaves nothing in the way of the next one.
  std::remove((file + ".active").c_str());
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0)
  {
    cv::RNG rng(3);
    MapWriter writer(file, PreprocessingParams());
    writer.add(keyframeMessage(randomKeyframe(rng), 1));
    raise(SIGKILL);
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  EXPECT_NO_THROW(checkMapTarget(file));
}

TEST_F(MapIoTest, AKilledWriterLeavesEverythingUpToTheLastFlush)
{
  const std::string file = path("killed.bag");
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0)
  {
    cv::RNG rng(3);
    MapWriter writer(file, PreprocessingParams());
    for (int k = 0; k < 10; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 1000 + k));
    writer.flush();
    for (int k = 10; k < 15; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 1000 + k));
    raise(SIGKILL);  // no destructor, no close
    _exit(0);
  }
  int status = 0;
  ASSERT_EQ(waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  const RouteMap map = readMap(file);
  ASSERT_EQ(map.size(), 10u);
  for (size_t k = 0; k < 10; ++k)
    EXPECT_EQ(map.stampNs(k), 1000 + static_cast<int64_t>(k));
}

TEST_F(MapIoTest, MapOrderSurvivesStampsThatJumpBackOrAreZero)
{
  const std::vector<int64_t> stamps = { 5000000000LL, 3000000000LL, 0, 0, 4000000000LL };
  cv::RNG rng(5);
  RouteMap map{ PreprocessingParams() };
  for (int64_t stamp : stamps)
    map.addKeyframe(randomKeyframe(rng), stamp);
  writeMap(path("map.bag"), map);
  const RouteMap read = readMap(path("map.bag"));
  ASSERT_EQ(read.size(), stamps.size());
  for (size_t k = 0; k < stamps.size(); ++k)
  {
    EXPECT_EQ(read.stampNs(k), stamps[k]);
    EXPECT_EQ(0, std::memcmp(read.keyframe(k), map.keyframe(k), map.keyframeBytes())) << "keyframe " << k;
  }
}

TEST_F(MapIoTest, MissingEmptyDirectoryAndForeignFilesAreNamed)
{
  EXPECT_NE(readError(path("none.bag")).find("does not exist"), std::string::npos);
  writeAll(path("left.bag.active"), "x");
  EXPECT_NE(readError(path("left.bag")).find("rosbag reindex"), std::string::npos) << readError(path("left.bag"));
  writeAll(path("empty.bag"), "");
  EXPECT_NE(readError(path("empty.bag")).find("is empty"), std::string::npos);
  EXPECT_NE(readError(dir_).find("is a directory"), std::string::npos);
  writeAll(path("text.bag"), "keyframe,stamp\n1,2\n");
  EXPECT_NE(readError(path("text.bag")).find("not a rosbag"), std::string::npos);
  writeAll(path("short.bag"), "#ROSBAG");
  EXPECT_NE(readError(path("short.bag")).find("truncated"), std::string::npos);
  // A finished map cut short was copied in part: copy it again. A recording's .active file cut short was
  // interrupted. A finished map is one chunk: cut in it, no keyframe is left for `rosbag reindex` to keep (it
  // was advised, and the reindexed file held nothing).
  const std::string whole = readAll(writeTestMap("whole.bag", 4));
  writeAll(path("half.bag"), whole.substr(0, whole.size() / 2));
  writeAll(path("half.bag.active"), whole.substr(0, whole.size() / 2));
  const std::string copied = readError(path("half.bag")), interrupted = readError(path("half.bag.active"));
  EXPECT_NE(copied.find("truncated or corrupt"), std::string::npos) << copied;
  EXPECT_NE(copied.find("copied only in part"), std::string::npos) << copied;
  EXPECT_NE(copied.find("Copy it again"), std::string::npos) << copied;
  EXPECT_NE(copied.find("no keyframe lies complete before the damage, so `rosbag reindex` recovers none"),
            std::string::npos)
      << copied;
  EXPECT_EQ(copied.find("a recording was interrupted"), std::string::npos) << copied;
  EXPECT_NE(interrupted.find("a recording was interrupted before any keyframe lay complete in it: nothing to recover"),
            std::string::npos)
      << interrupted;
  // Flushed twice (4 keyframes, then 2) and cut in the second chunk: the first chunk's 4 can be kept.
  {
    cv::RNG rng(3);
    MapWriter writer(path("two_chunks.bag"), PreprocessingParams());
    for (int k = 0; k < 4; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 10 + k));
    writer.flush();
    for (int k = 0; k < 2; ++k)
      writer.add(keyframeMessage(randomKeyframe(rng), 20 + k));
    writer.flush();
    const std::string two = readAll(path("two_chunks.bag"));
    // Cut 3000 bytes into the second chunk record (its header holds the field op=0x05, as the first's does).
    const std::string chunk_op("op=\x05", 4);
    const size_t second_chunk = two.find(chunk_op, two.find(chunk_op) + 1);
    ASSERT_NE(second_chunk, std::string::npos);
    ASSERT_LT(second_chunk + 3000, two.size());
    writeAll(path("cut_two.bag"), two.substr(0, second_chunk + 3000));
    writeAll(path("cut_two.bag.active"), two.substr(0, second_chunk + 3000));
  }
  const std::string kept = readError(path("cut_two.bag")), flushed = readError(path("cut_two.bag.active"));
  EXPECT_NE(kept.find("or keep the 4 keyframes before the damage with `rosbag reindex " + path("cut_two.bag") + "`"),
            std::string::npos)
      << kept;
  EXPECT_NE(flushed.find("a recording was interrupted: `rosbag reindex " + path("cut_two.bag.active") +
                         "` may recover the 4 keyframes it had flushed before the damage"),
            std::string::npos)
      << flushed;
  EXPECT_NE(readError("").find("no map file"), std::string::npos);
}

TEST_F(MapIoTest, TruncatedMapsAreRefusedAtEveryLength)
{
  const std::string bytes = readAll(writeTestMap("map.bag", 4));
  ASSERT_GT(bytes.size(), 4u * 2048u);
  int refused = 0;
  for (size_t length = 13; length < bytes.size(); length += 61)
  {
    writeAll(path("cut.bag"), bytes.substr(0, length));
    const std::string error = readError(path("cut.bag"));
    EXPECT_FALSE(error.empty()) << "a map cut at " << length << " of " << bytes.size() << " bytes was read";
    EXPECT_NE(error.find("cut.bag"), std::string::npos) << error;
    refused += !error.empty();
  }
  EXPECT_GT(refused, 100);
}

TEST_F(MapIoTest, CorruptBytesGiveMapErrorOrAMapNeverACrash)
{
  const std::string bytes = readAll(writeTestMap("map.bag", 3));
  std::string broken = bytes;
  broken[13] = '\xff';  // the length of the bag header record
  broken[14] = '\xff';
  broken[15] = '\xff';
  writeAll(path("header.bag"), broken);
  EXPECT_FALSE(readError(path("header.bag")).empty());

  for (size_t position = 13; position < bytes.size(); position += 37)
  {
    broken = bytes;
    broken[position] = static_cast<char>(~broken[position]);
    writeAll(path("flipped.bag"), broken);
    try
    {
      const RouteMap map = readMap(path("flipped.bag"));
      EXPECT_EQ(map.size(), 3u) << "byte " << position;  // a flipped pixel: still a 3-keyframe map
    }
    catch (const MapError&)
    {
    }
  }
}

TEST_F(MapIoTest, BagsThatAreNotMapsAreNamedForWhatTheyLack)
{
  const PreprocessingParams params;
  cv::RNG rng(9);
  {
    rosbag::Bag bag(path("no_keyframes.bag"), rosbag::bagmode::Write);
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text(params.serialize()));
  }
  EXPECT_NE(readError(path("no_keyframes.bag")).find("holds no keyframes"), std::string::npos);
  {
    rosbag::Bag bag(path("no_params.bag"), rosbag::bagmode::Write);
    bag.write(kMapKeyframesTopic, ros::TIME_MIN, keyframeMessage(randomKeyframe(rng), 1));
  }
  EXPECT_NE(readError(path("no_params.bag")).find("no preprocessing parameters"), std::string::npos);
  {
    rosbag::Bag bag(path("bad_params.bag"), rosbag::bagmode::Write);
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text("output_width=64;output_height=banana"));
    bag.write(kMapKeyframesTopic, ros::TIME_MIN, keyframeMessage(randomKeyframe(rng), 1));
  }
  EXPECT_NE(readError(path("bad_params.bag")).find("invalid preprocessing parameters"), std::string::npos);
  {
    rosbag::Bag bag(path("sizes.bag"), rosbag::bagmode::Write);
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text(params.serialize()));
    bag.write(kMapKeyframesTopic, ros::Time(1), keyframeMessage(randomKeyframe(rng), 1));
    bag.write(kMapKeyframesTopic, ros::Time(2), keyframeMessage(randomKeyframe(rng, 32, 16), 2));
  }
  const std::string sizes = readError(path("sizes.bag"));
  EXPECT_NE(sizes.find("keyframe 1 is 32x16 px"), std::string::npos) << sizes;
  EXPECT_NE(sizes.find("inconsistent keyframe sizes"), std::string::npos) << sizes;
  {
    rosbag::Bag bag(path("color.bag"), rosbag::bagmode::Write);
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text(params.serialize()));
    sensor_msgs::ImagePtr color = keyframeMessage(randomKeyframe(rng), 1);
    color->encoding = sensor_msgs::image_encodings::BGR8;
    bag.write(kMapKeyframesTopic, ros::Time(1), color);
  }
  EXPECT_NE(readError(path("color.bag")).find("encoding 'bgr8'"), std::string::npos);
  {
    rosbag::Bag bag(path("strings.bag"), rosbag::bagmode::Write);
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text(params.serialize()));
    bag.write(kMapKeyframesTopic, ros::Time(1), text("not an image"));
  }
  EXPECT_NE(readError(path("strings.bag")).find("expected sensor_msgs/Image"), std::string::npos);
  {
    rosbag::Bag bag(path("future.bag"), rosbag::bagmode::Write);
    bag.write(kMapInfoTopic, ros::TIME_MIN, text("format=2;writer=tomorrow"));
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text(params.serialize()));
    bag.write(kMapKeyframesTopic, ros::Time(1), keyframeMessage(randomKeyframe(rng), 1));
  }
  EXPECT_NE(readError(path("future.bag")).find("map format 2"), std::string::npos);
  // A compressed camera bag given as the map was told to `rosbag decompress` itself, and then that it held
  // no parameters: it is said to be no map at once, naming its topics. A compressed map is still told to
  // be decompressed.
  {
    rosbag::Bag bag(path("camera.bag"), rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::LZ4);
    bag.write("/camera/image_raw", ros::Time(1), keyframeMessage(randomKeyframe(rng), 1));
  }
  EXPECT_EQ(readError(path("camera.bag")),
            "'" + path("camera.bag") + "' is a bag (lz4-compressed; topics /camera/image_raw), not a map file: a map "
            "has the topics 'keyframes' and 'preprocessing' (written by the map recorder, teach.launch, or "
            "`localize_offline --save-map`)");
  {
    rosbag::Bag bag(path("compressed_map.bag"), rosbag::bagmode::Write);
    bag.setCompression(rosbag::compression::BZ2);
    bag.write(kMapPreprocessingTopic, ros::TIME_MIN, text(params.serialize()));
    bag.write(kMapKeyframesTopic, ros::Time(1), keyframeMessage(randomKeyframe(rng), 1));
  }
  EXPECT_NE(readError(path("compressed_map.bag")).find("has compressed chunks (bz2)"), std::string::npos);
  EXPECT_NE(readError(path("compressed_map.bag")).find("rosbag decompress"), std::string::npos);
}

TEST_F(MapIoTest, WriterRefusesKeyframesThatDoNotMatchItsParameters)
{
  cv::RNG rng(11);
  MapWriter writer(path("map.bag"), PreprocessingParams());
  EXPECT_THROW(writer.add(keyframeMessage(randomKeyframe(rng, 32, 16), 1)), MapError);
  sensor_msgs::ImagePtr color = keyframeMessage(randomKeyframe(rng), 1);
  color->encoding = sensor_msgs::image_encodings::BGR8;
  EXPECT_THROW(writer.add(color), MapError);
  writer.close();
  EXPECT_FALSE(exists(path("map.bag"))) << "nothing recorded, nothing written";
  EXPECT_FALSE(exists(path("map.bag.active")));
  EXPECT_THROW(MapWriter(path("no/such/dir/map.bag"), PreprocessingParams()), MapError);
}

KeyframeMotionPtr keyframeMotion(double linear_mps, double angular_rps, double distance_m, uint32_t keyframe = 99)
{
  KeyframeMotionPtr motion = boost::make_shared<KeyframeMotion>();
  motion->keyframe = keyframe;  // the writer numbers them in map order, whatever this says
  motion->linear_mps = linear_mps;
  motion->angular_rps = angular_rps;
  motion->distance_m = distance_m;
  return motion;
}

TEST_F(MapIoTest, TaughtMotionRoundTripsInMapOrderAcrossFlushes)
{
  cv::RNG rng(3);
  const std::string file = path("motion.bag");
  {
    MapWriter writer(file, PreprocessingParams());
    writer.add(keyframeMessage(randomKeyframe(rng), 1000000000LL), keyframeMotion(0.5, 0.0, 0.0));
    writer.add(keyframeMessage(randomKeyframe(rng), 2000000000LL));  // none recorded for keyframe 1
    writer.add(keyframeMessage(randomKeyframe(rng), 3000000000LL), keyframeMotion(0.75, -0.25, 1.5));
    writer.flush();
    writer.add(keyframeMessage(randomKeyframe(rng), 4000000000LL), keyframeMotion(1.0, 0.125, 0.875));
    writer.add(keyframeMessage(randomKeyframe(rng), 5000000000LL), keyframeMotion(0.25, 0.5, 0.0625));
    writer.close();
  }
  EXPECT_EQ(5u, readMap(file).size());
  const std::map<int, TaughtMotion> motion = readTaughtMotion(file);
  ASSERT_EQ(4u, motion.size());
  EXPECT_EQ(0u, motion.count(1));
  const int indices[] = { 0, 2, 3, 4 };
  const double linear[] = { 0.5, 0.75, 1.0, 0.25 }, angular[] = { 0.0, -0.25, 0.125, 0.5 },
               distance[] = { 0.0, 1.5, 0.875, 0.0625 };
  for (int i = 0; i < 4; ++i)
  {
    ASSERT_EQ(1u, motion.count(indices[i])) << "keyframe " << indices[i];
    EXPECT_EQ(linear[i], motion.at(indices[i]).linear_mps) << "keyframe " << indices[i];
    EXPECT_EQ(angular[i], motion.at(indices[i]).angular_rps) << "keyframe " << indices[i];
    EXPECT_EQ(distance[i], motion.at(indices[i]).distance_m) << "keyframe " << indices[i];
  }
}

TEST_F(MapIoTest, MapsWithoutTaughtMotionLoadAndSayTheyHaveNone)
{
  const std::string file = writeTestMap("old.bag", 4);
  EXPECT_EQ(4u, readMap(file).size());
  EXPECT_TRUE(readTaughtMotion(file).empty());
}

TEST_F(MapIoTest, AMotionTopicOfAnotherTypeIsNamed)
{
  const std::string file = writeTestMap("foreign.bag", 2);
  {
    rosbag::Bag bag(file, rosbag::bagmode::Append);
    bag.write(kMapMotionTopic, ros::Time(100, 0), text("not a motion"));
  }
  EXPECT_EQ(2u, readMap(file).size());  // still a map for localization
  try
  {
    readTaughtMotion(file);
    ADD_FAILURE() << "no MapError";
  }
  catch (const MapError& e)
  {
    EXPECT_NE(std::string(e.what()).find("has type std_msgs/String"), std::string::npos) << e.what();
  }
}

TEST(MapIo, ParameterDifferenceNamesTheFieldsThatDiffer)
{
  PreprocessingParams a, b;
  b.output_width = 32;
  b.sky_fraction = 0.25;
  const std::string difference = preprocessingDifference(a, b);
  EXPECT_NE(difference.find("output_width: 64 vs 32"), std::string::npos) << difference;
  EXPECT_NE(difference.find("sky_fraction: 0 vs 0.25"), std::string::npos) << difference;
  // Values read as typed, not as serialized to round-trip (0.10000000000000001).
  b.normalization_strength = 0.2;
  EXPECT_NE(preprocessingDifference(a, b).find("normalization_strength: 0.1 vs 0.2,"), std::string::npos)
      << preprocessingDifference(a, b);
  EXPECT_EQ(difference.find("patch_size"), std::string::npos) << difference;
  EXPECT_EQ(preprocessingDifference(a, a), "");
  // Whole numbers as typed: 100, not 1e+02 (the shortest form that reads back).
  PreprocessingParams wide;
  wide.output_width = 100;
  EXPECT_NE(preprocessingDifference(a, wide).find("output_width: 64 vs 100"), std::string::npos)
      << preprocessingDifference(a, wide);
}

TEST(MapIo, ParametersTopicSitsNextToTheImageTopic)
{
  EXPECT_EQ(preprocessingParamsTopic("/image_preprocessed"), "/preprocessing_params");
  EXPECT_EQ(preprocessingParamsTopic("/robot/front/image_preprocessed"), "/robot/front/preprocessing_params");
}

}  // namespace
}  // namespace along_route_localization

int main(int argc, char** argv)
{
  ::testing::InitGoogleTest(&argc, argv);
  return RUN_ALL_TESTS();
}
