// Publishing a nodelet's diagnostics on a wall-clock timer that survives ROS time going back.
#ifndef ALONG_ROUTE_LOCALIZATION_ROS_DIAGNOSTICS_TIMER_H
#define ALONG_ROUTE_LOCALIZATION_ROS_DIAGNOSTICS_TIMER_H

#include <memory>

#include <diagnostic_updater/diagnostic_updater.h>
#include <ros/ros.h>

namespace along_route_localization
{

/// A wall timer (every 0.25 s) that lets `updater` publish when its period has passed. The updater
/// publishes when ROS time has passed its last publication + its period; a looping bag played with
/// --clock sends ROS time back, and the updater would wait for the old time: where ROS time went back
/// since the last tick, the timer forces an update. Keep the returned timer alive.
ros::WallTimer startDiagnosticsTimer(ros::NodeHandle& nh, const std::shared_ptr<diagnostic_updater::Updater>& updater);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_ROS_DIAGNOSTICS_TIMER_H
