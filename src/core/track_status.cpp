#include "along_route_localization/track_status.h"

#include <algorithm>
#include <cmath>

namespace along_route_localization
{

void GlobalConfirmation::configure(int frames, int max_step)
{
  frames_ = std::max(1, frames);
  max_step_ = std::max(1, max_step);
  clear();
}

void GlobalConfirmation::clear()
{
  count_ = 0;
  previous_keyframe_ = -1;
  frames_since_previous_ = 0;
}

bool GlobalConfirmation::update(int keyframe, bool confident, bool informative)
{
  ++frames_since_previous_;
  if (!informative)
    return false;
  const int advance = keyframe - previous_keyframe_;
  const bool consistent =
      previous_keyframe_ >= 0 && advance >= 0 && advance <= max_step_ * frames_since_previous_;
  count_ = !confident ? 0 : (consistent ? count_ + 1 : 1);
  previous_keyframe_ = keyframe;
  frames_since_previous_ = 0;
  return count_ >= frames_;
}

void LossDetector::configure(int low_frames, int window)
{
  window = std::max(1, window);
  low_frames_ = std::min(std::max(1, low_frames), window);
  history_.assign(static_cast<size_t>(window), 0);
  clear();
}

void LossDetector::clear()
{
  std::fill(history_.begin(), history_.end(), 0);
  next_ = filled_ = low_count_ = 0;
}

bool LossDetector::update(bool confident, bool informative)
{
  if (!informative)
    return false;
  const int window = static_cast<int>(history_.size());
  if (filled_ == window)
    low_count_ -= history_[next_];  // the oldest frame leaves the window
  else
    ++filled_;
  history_[next_] = confident ? 0 : 1;
  low_count_ += history_[next_];
  next_ = (next_ + 1) % window;
  return low_count_ >= low_frames_;
}

double FrameClock::periodNs() const
{
  if (intervals_.size() < static_cast<size_t>(kMinIntervals))
    return 0.0;
  std::vector<int64_t> sorted = intervals_;
  const size_t middle = sorted.size() / 2;
  std::nth_element(sorted.begin(), sorted.begin() + middle, sorted.end());
  if (sorted.size() % 2 == 1)
    return static_cast<double>(sorted[middle]);
  const int64_t upper = sorted[middle];
  const int64_t lower = *std::max_element(sorted.begin(), sorted.begin() + middle);
  return 0.5 * (static_cast<double>(lower) + static_cast<double>(upper));
}

FrameClock::Tick FrameClock::update(int64_t stamp_ns)
{
  Tick tick;
  if (stamp_ns == 0)
  {
    last_ns_ = 0;  // a frame came: the interval to the next stamp is not one period
    return tick;
  }
  const double period = periodNs();
  if (last_ns_ != 0 && stamp_ns < last_ns_)
  {
    if (period > 0.0 && static_cast<double>(last_ns_ - stamp_ns) < kOutOfOrderRatio * period)
      return tick;  // a frame out of order: neither time going back nor an interval
    tick.went_back = true;
  }
  else if (last_ns_ != 0 && stamp_ns > last_ns_)
  {
    const int64_t interval = stamp_ns - last_ns_;
    if (period > 0.0)
    {
      const double ratio = std::min(static_cast<double>(interval) / period, 1e9);
      if (ratio >= kGapRatio)
        tick.missed = static_cast<int>(std::lround(ratio)) - 1;
    }
    if (intervals_.size() < static_cast<size_t>(kIntervals))
      intervals_.push_back(interval);
    else
      intervals_[next_] = interval;
    next_ = (next_ + 1) % kIntervals;
  }
  last_ns_ = stamp_ns;
  return tick;
}

}  // namespace along_route_localization
