// A nodelet's private parameters: which of those set on the parameter server it does not read.
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_PRIVATE_PARAMETERS_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_PRIVATE_PARAMETERS_H

#include <set>
#include <string>
#include <vector>

#include <boost/any.hpp>
#include <XmlRpcValue.h>
#include <ros/node_handle.h>

namespace along_route_localization
{

/// The names set directly under private_nh's namespace (`~name`, not `~group/name`) that are not in
/// `read`: a misspelt or misplaced parameter would otherwise be ignored without a word. Sorted.
std::vector<std::string> unreadParameters(const ros::NodeHandle& private_nh, const std::set<std::string>& read);

/// The names of a dynamic_reconfigure config's parameters (Config = e.g. LocalizerConfig).
template <class Config>
std::set<std::string> configParameterNames()
{
  std::set<std::string> names;
  for (const auto& description : Config::__getParamDescriptions__())
    names.insert(description->name);
  return names;
}

/// A parameter's value as text: a string as it is, a number with `digits` significant digits (17: the
/// double exactly, to be parsed again), true / false; XML for a list or a dictionary.
std::string parameterText(const XmlRpc::XmlRpcValue& value, int digits);

/// A parameter's value as a log shows it (parameterText, 6 digits): 'text' for a string, 2.5, 3, true.
std::string parameterValueText(const XmlRpc::XmlRpcValue& value);

/// A number as the logs show it: 6 significant digits, no trailing zeros (1, 2.5, 1e-09).
std::string numberText(double value);

/// Whether an integer parameter can take `value` as it is: an integer, or a number with no fraction in the
/// int range (100.0, which roscpp reads as 100); not a fraction (roscpp would round 2.5 to 3), a string or
/// a bool.
bool readableAsInt(const XmlRpc::XmlRpcValue& value);

/// "~name = value is not an integer; refused, keeping default".
std::string mistypedSentence(const std::string& name, const XmlRpc::XmlRpcValue& value, const std::string& type,
                             const std::string& kept);

/// For each parameter of a dynamic_reconfigure config set under private_nh with a value of another type
/// (a string for a number, a fraction for an integer): a sentence for the log, and the config's default
/// set in its place on the parameter server, so that the reconfigure server starts from the value the
/// sentence says is kept (it would keep the default for a string without a word, and read a fraction for
/// an integer rounded by roscpp: 12.7 as 13, NaN as INT_MIN). Call before creating the reconfigure server.
/// (A value of the right type outside the working range reaches the config callback, which corrects it.)
template <class Config>
std::vector<std::string> mistypedParameters(const ros::NodeHandle& private_nh)
{
  const Config defaults = Config::__getDefault__();
  std::vector<std::string> sentences;
  for (const auto& description : Config::__getParamDescriptions__())
  {
    XmlRpc::XmlRpcValue value;
    if (!private_nh.getParam(description->name, value))
      continue;
    const XmlRpc::XmlRpcValue::Type type = value.getType();
    bool readable = false;
    if (description->type == "int")
      readable = readableAsInt(value);
    else if (description->type == "double")
      readable = type == XmlRpc::XmlRpcValue::TypeInt || type == XmlRpc::XmlRpcValue::TypeDouble;
    else if (description->type == "str")
      readable = type == XmlRpc::XmlRpcValue::TypeString;
    else if (description->type == "bool")
      readable = type == XmlRpc::XmlRpcValue::TypeBoolean;
    if (readable)
      continue;
    boost::any kept;
    description->getValue(defaults, kept);
    std::string kept_text;
    if (description->type == "int")
    {
      kept_text = std::to_string(boost::any_cast<int>(kept));
      private_nh.setParam(description->name, boost::any_cast<int>(kept));
    }
    else if (description->type == "double")
    {
      kept_text = numberText(boost::any_cast<double>(kept));
      private_nh.setParam(description->name, boost::any_cast<double>(kept));
    }
    else if (description->type == "str")
    {
      kept_text = boost::any_cast<std::string>(kept);
      private_nh.setParam(description->name, kept_text);
    }
    else
    {
      kept_text = boost::any_cast<bool>(kept) ? "true" : "false";
      private_nh.setParam(description->name, boost::any_cast<bool>(kept));
    }
    sentences.push_back(mistypedSentence(description->name, value, description->type, kept_text));
  }
  return sentences;
}

/// "~ring_bufer_rows is not a parameter of the <who> and is ignored (did you mean ring_buffer_rows?).
/// It reads: a, b, c"; for a parameter this version removed, "~" + removedParameterSentence(name) + "; the value
/// given is ignored".
std::string unreadSentence(const std::string& name, const std::string& who, const std::set<std::string>& read);

/// "a, b, c".
std::string joined(const std::set<std::string>& names);

/// What a nodelet reads the robot's velocity from, on its topic `motion` (~motion_type): nothing, a
/// geometry_msgs/Twist (e.g. the robot's cmd_vel) or a nav_msgs/Odometry (its twist, and its poses).
enum class MotionType
{
  kNone,
  kTwist,
  kOdometry
};

/// "none", "twist" or "odometry": the values ~motion_type takes.
std::string motionTypeName(MotionType type);

/// ~motion_type as set under private_nh; `fallback` when unset. A value that is not one of
/// none | twist | odometry (or not a string) gives `fallback`, and *problem the sentence for the log
/// ("~motion_type 'cmd_vel' is not one of none | twist | odometry; using twist"); else *problem is empty.
MotionType readMotionType(const ros::NodeHandle& private_nh, MotionType fallback, std::string* problem);

/// "" unless the master lists `topic` (resolved) with another message type than ~motion_type `type` reads;
/// then the sentence saying so and which ~motion_type would read it. roscpp drops such a connection with a
/// line in the publisher's log only, so the motion topic stayed silent without a word (a teach recorded
/// no taught motion, and the route follower refused the map later).
std::string motionTopicTypeProblem(const std::string& topic, MotionType type);

/// A static bool parameter as set under private_nh; `fallback` when unset. Takes a bool, the integers 0
/// and 1 (roslaunch types `value="0"` as an integer, which ros::NodeHandle::param<bool> ignores without a
/// word: `teach.launch autostart:=0` recorded from the first frame) and the strings true / false / 1 / 0 /
/// yes / no / on / off; anything else gives `fallback`, set in its place on the parameter server, and
/// *problem the sentence for the log ("~autostart = 'maybe' is not true or false; using true"); else
/// *problem is empty.
bool readBoolParameter(const ros::NodeHandle& private_nh, const std::string& name, bool fallback, std::string* problem);

/// A static integer parameter as set under private_nh; `fallback` when unset. Takes what readableAsInt
/// takes: a fraction (which ros::NodeHandle::param<int> reads rounded, 2.5 as 3, without a word), a string
/// or a bool gives `fallback`, set in its place on the parameter server, and *problem the sentence for the
/// log ("~queue_size = 2.5 is not an integer; refused, keeping 100"); else *problem is empty. The range is
/// the caller's to check.
int readIntParameter(const ros::NodeHandle& private_nh, const std::string& name, int fallback, std::string* problem);

/// A static number parameter as set under private_nh; `fallback` when unset. Takes an integer or a
/// fraction; a string or a bool (which ros::NodeHandle::param<double> ignores without a word) gives
/// `fallback`, set in its place on the parameter server, and *problem the sentence for the log; else
/// *problem is empty.
double readDoubleParameter(const ros::NodeHandle& private_nh, const std::string& name, double fallback,
                           std::string* problem);

/// A static string parameter (a path) as set under private_nh; `fallback` when unset. Anything but a
/// string (`map: 2024`, which ros::NodeHandle::param<std::string> ignores without a word) gives `fallback`
/// and *problem the sentence for the log; else *problem is empty.
std::string readStringParameter(const ros::NodeHandle& private_nh, const std::string& name,
                                const std::string& fallback, std::string* problem);

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_PRIVATE_PARAMETERS_H
