#include "glue/diagnostics.h"

#include <algorithm>

namespace along_route_localization
{

ros::WallTimer startDiagnosticsTimer(ros::NodeHandle& nh, const std::shared_ptr<diagnostic_updater::Updater>& updater)
{
  // The ROS time at the last tick; only this timer's callback uses it.
  auto last_tick = std::make_shared<ros::Time>();
  return nh.createWallTimer(ros::WallDuration(0.25), [updater, last_tick](const ros::WallTimerEvent&) {
    const ros::Time now = ros::Time::now();
    if (now < *last_tick)
      updater->force_update();
    else
      updater->update();
    *last_tick = now;
  });
}

bool DroppedFrames::drop(int kind, const std::string& reason)
{
  ++count_;
  newest_dropped_ = true;
  last_reason_ = reason;
  last_kind_ = kind;
  auto same = std::find_if(kinds_.begin(), kinds_.end(), [kind](const Kind& k) { return k.kind == kind; });
  if (same == kinds_.end())
    kinds_.push_back(Kind{ kind, 1, reason });
  else
  {
    ++same->count;
    same->reason = reason;
  }
  const ros::WallTime now = ros::WallTime::now();
  ros::WallTime& last = last_logged_[kind];
  if (!last.isZero() && (now - last).toSec() < 5.0)
    return false;
  last = now;
  return true;
}

std::string DroppedFrames::byKind(const std::string& noun) const
{
  std::string text;
  for (const Kind& k : kinds_)
    text += (text.empty() ? "" : "; ") + std::to_string(k.count) + " " + noun + (k.count == 1 ? "" : "s") + ": " +
            k.reason;
  return text;
}

void DroppedFrames::addTo(diagnostic_updater::DiagnosticStatusWrapper& stat, const std::string& noun) const
{
  stat.add(noun + "s dropped", count_);
  stat.add("last dropped " + noun, last_reason_.empty() ? std::string("(none)") : last_reason_);
}

}  // namespace along_route_localization
