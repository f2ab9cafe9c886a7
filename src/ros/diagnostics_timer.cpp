#include "ros/diagnostics_timer.h"

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

}  // namespace along_route_localization
