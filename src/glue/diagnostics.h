// What the nodelets share for their /diagnostics: a timer that survives ROS time going back, and the
// record of the frames a nodelet did not use.
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_DIAGNOSTICS_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_DIAGNOSTICS_H

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

namespace along_route_localization
{

/// A wall timer (every 0.25 s) that lets `updater` publish when its period has passed. The updater
/// publishes when ROS time has passed its last publication + its period; a looping bag played with
/// --clock sends ROS time back, and the updater would wait for the old time: where ROS time went back
/// since the last tick, the timer forces an update. Keep the returned timer alive.
ros::WallTimer startDiagnosticsTimer(ros::NodeHandle& nh, const std::shared_ptr<diagnostic_updater::Updater>& updater);

/// The frames a nodelet did not use: how many, why the last one was not, whether the newest one was
/// not, and when each kind of reason may be logged again. Used from one callback queue only.
class DroppedFrames
{
public:
  /// Counts a frame not used for `reason` (a sentence); `kind` is the caller's kind of reason. True
  /// when the caller should log it now: at most once per 5 s for each kind, so a second kind is said
  /// at once.
  bool drop(int kind, const std::string& reason);
  /// The newest frame was used.
  void used() { newest_dropped_ = false; }

  uint64_t count() const { return count_; }
  bool newestDropped() const { return newest_dropped_; }
  const std::string& lastReason() const { return last_reason_; }
  int lastKind() const { return last_kind_; }
  /// "243 frames: the preprocessing parameters changed during the teach (...); 1 frame: waiting for ..." --
  /// the count of each kind with its latest reason, in the order the kinds first came; empty when none.
  std::string byKind(const std::string& noun) const;
  /// Adds "<noun> dropped" (the count) and "last dropped <noun>" (the reason, or "(none)").
  void addTo(diagnostic_updater::DiagnosticStatusWrapper& stat, const std::string& noun) const;

private:
  uint64_t count_ = 0;
  bool newest_dropped_ = false;
  std::string last_reason_;
  int last_kind_ = 0;
  std::map<int, ros::WallTime> last_logged_;
  struct Kind
  {
    int kind;
    uint64_t count;
    std::string reason;  // the latest
  };
  std::vector<Kind> kinds_;
};

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_DIAGNOSTICS_H
