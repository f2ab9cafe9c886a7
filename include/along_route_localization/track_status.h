// Step 5, the status part: when a global answer may be trusted (initialization, relocalization) and
// when the track is lost. Both decide on a frame's "confidence in the place" (Localizer::process)
// and skip featureless frames: a dark tunnel or a blank frame says nothing about where we are, so it
// neither confirms a hypothesis nor counts against the track. FrameClock tells, from the frames'
// stamps, when time went back (a looping bag) or frames were missed (a camera dropout).
#ifndef ALONG_ROUTE_LOCALIZATION_TRACK_STATUS_H
#define ALONG_ROUTE_LOCALIZATION_TRACK_STATUS_H

#include <cstddef>
#include <cstdint>
#include <vector>

namespace along_route_localization
{

/// A global search over N keyframes with few rows finds some path that looks confident now and then
/// (many candidates, few rows). A hypothesis is accepted only after `frames` consecutive informative
/// frames whose global answer was confident and moved along the route like the robot can: 0 to
/// max_step keyframes per frame since the previous informative frame.
class GlobalConfirmation
{
public:
  GlobalConfirmation(int frames = 1, int max_step = 1) { configure(frames, max_step); }
  void configure(int frames, int max_step);
  void clear();
  /// One frame of global search: its best end keyframe and whether it was confident. Returns true when
  /// the hypothesis is confirmed (then call clear() once it is taken).
  bool update(int keyframe, bool confident, bool informative);
  int count() const { return count_; }

private:
  int frames_ = 1, max_step_ = 1;
  int count_ = 0;                 // consecutive confident, consistent informative answers
  int previous_keyframe_ = -1;    // answer of the last informative frame counted
  int frames_since_previous_ = 0; // frames (informative or not) since then
};

/// Lost when at least `low_frames` of the last `window` informative frames had low confidence. A
/// window instead of a run of consecutive frames: off the route the confidence is low most of the time
/// but not always (any textured frame resembles some keyframe a little), and one lucky frame must not
/// restart the count.
class LossDetector
{
public:
  LossDetector(int low_frames = 1, int window = 1) { configure(low_frames, window); }
  void configure(int low_frames, int window);  ///< clears the history
  void clear();
  /// Returns true when the track is lost (then call clear()). informative = false: the frame is not
  /// counted (the Localizer passes false for a featureless frame and for a copy of the last view).
  bool update(bool confident, bool informative);
  int lowFrames() const { return low_count_; }

private:
  int low_frames_ = 1;
  std::vector<uint8_t> history_;  // circular: 1 = low confidence, over the last window informative frames
  int next_ = 0, filled_ = 0, low_count_ = 0;
};

/// The camera's frame period, from the frames' stamps, and what a new stamp says about the sequence:
/// time went back (a looping bag, a restarted clock), or a gap in which frames were missed (a dropout, a
/// cable, frames dropped on the way). The period is the median of the last kIntervals intervals, known
/// once kMinIntervals were seen (a gap before that is not noticed). A stamp `ratio` periods after the
/// last one missed lround(ratio) - 1 frames when ratio >= kGapRatio: a camera's jitter is far below half a
/// period, and a rate that changes for good is learnt within kIntervals / 2 frames. A stamp less than
/// kOutOfOrderRatio periods before the last one is a frame out of order, not time going back.
class FrameClock
{
public:
  static constexpr int kIntervals = 15;
  static constexpr int kMinIntervals = 5;
  static constexpr double kGapRatio = 1.5;
  static constexpr double kOutOfOrderRatio = 0.5;

  struct Tick
  {
    bool went_back = false;  ///< the stamp is before the last one
    int missed = 0;          ///< frames missed between the last stamp and this one
  };
  /// stamp_ns: the frame's stamp (any epoch). 0 means unknown: nothing is said or learnt, and the next
  /// stamp starts afresh.
  Tick update(int64_t stamp_ns);
  /// Forgets the last stamp (the next one starts afresh) but keeps the period.
  void forgetLastStamp() { last_ns_ = 0; }
  /// The period in ns, 0 while fewer than kMinIntervals intervals were seen.
  double periodNs() const;

private:
  int64_t last_ns_ = 0;
  std::vector<int64_t> intervals_;  // circular, the last kIntervals positive intervals
  std::size_t next_ = 0;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_TRACK_STATUS_H
