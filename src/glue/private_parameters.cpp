#include "glue/private_parameters.h"

#include <ros/master.h>

#include "along_route_localization/parameters.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>

namespace along_route_localization
{

std::vector<std::string> unreadParameters(const ros::NodeHandle& private_nh, const std::set<std::string>& read)
{
  std::vector<std::string> all, unread;
  if (!private_nh.getParamNames(all))
    return unread;
  const std::string prefix = private_nh.getNamespace() + "/";
  for (const std::string& key : all)  // each name once: they are the parameter server's keys
  {
    if (key.compare(0, prefix.size(), prefix) != 0)
      continue;
    const std::string name = key.substr(prefix.size());
    if (name.empty() || name.find('/') != std::string::npos || read.count(name))
      continue;
    unread.push_back(name);
  }
  std::sort(unread.begin(), unread.end());
  return unread;
}

namespace
{

std::string numberText(double value, int digits)
{
  std::ostringstream text;
  text.precision(digits);
  text << value;
  return text.str();
}

}  // namespace

std::string parameterText(const XmlRpc::XmlRpcValue& value, int digits)
{
  XmlRpc::XmlRpcValue& v = const_cast<XmlRpc::XmlRpcValue&>(value);  // XmlRpcValue's casts are not const
  switch (value.getType())
  {
    case XmlRpc::XmlRpcValue::TypeString:
      return static_cast<std::string>(v);
    case XmlRpc::XmlRpcValue::TypeDouble:
      return numberText(static_cast<double>(v), digits);
    case XmlRpc::XmlRpcValue::TypeInt:
      return std::to_string(static_cast<int>(v));
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return static_cast<bool>(v) ? "true" : "false";
    default:
      return v.toXml();  // a list, a dictionary, a date: rare enough to show as the server has it
  }
}

std::string parameterValueText(const XmlRpc::XmlRpcValue& value)
{
  const std::string text = parameterText(value, 6);
  return value.getType() == XmlRpc::XmlRpcValue::TypeString ? "'" + text + "'" : text;
}

std::string numberText(double value)
{
  return numberText(value, 6);
}

bool readableAsInt(const XmlRpc::XmlRpcValue& value)
{
  if (value.getType() == XmlRpc::XmlRpcValue::TypeInt)
    return true;
  if (value.getType() != XmlRpc::XmlRpcValue::TypeDouble)
    return false;
  const double number = static_cast<double>(const_cast<XmlRpc::XmlRpcValue&>(value));
  return std::isfinite(number) && number == std::floor(number) &&
         number >= static_cast<double>(std::numeric_limits<int>::min()) &&
         number <= static_cast<double>(std::numeric_limits<int>::max());
}

std::string mistypedSentence(const std::string& name, const XmlRpc::XmlRpcValue& value, const std::string& type,
                             const std::string& kept)
{
  const std::string wanted = type == "int" ? "an integer" : type == "double" ? "a number" :
                             type == "str" ? "a string" : "true or false";
  return "~" + name + " = " + parameterValueText(value) + " is not " + wanted + "; refused, keeping " + kept;
}

std::string unreadSentence(const std::string& name, const std::string& who, const std::set<std::string>& read)
{
  const std::string removed = removedParameterSentence(name);
  if (!removed.empty())
    return "~" + removed + "; the value given is ignored";
  std::string sentence = "~" + name + " is not a parameter of the " + who + " and is ignored";
  std::set<std::string> similar;
  for (const std::string& other : similarParameterNames(name))
    if (read.count(other))
      similar.insert(other);
  sentence += similar.empty() ? " (misspelt?)" : " (did you mean " + joined(similar) + "?)";
  return sentence + ". It reads: " + joined(read);
}

std::string joined(const std::set<std::string>& names)
{
  std::string text;
  for (const std::string& name : names)
    text += (text.empty() ? "" : ", ") + name;
  return text;
}

namespace
{

// Whether `name` is set under private_nh, its value then in *value; *problem cleared either way.
bool givenParameter(const ros::NodeHandle& private_nh, const std::string& name, XmlRpc::XmlRpcValue* value,
                    std::string* problem)
{
  problem->clear();
  return private_nh.getParam(name, *value);
}

}  // namespace

std::string motionTopicTypeProblem(const std::string& topic, MotionType type)
{
  if (type == MotionType::kNone)
    return std::string();
  const std::string expected = type == MotionType::kTwist ? "geometry_msgs/Twist" : "nav_msgs/Odometry";
  ros::master::V_TopicInfo topics;
  if (!ros::master::getTopics(topics))
    return std::string();  // no master to ask: nothing known
  for (const ros::master::TopicInfo& info : topics)
  {
    if (info.name != topic || info.datatype == expected)
      continue;
    const std::string reads = info.datatype == "geometry_msgs/Twist" ? " (~motion_type twist reads it)" :
                              info.datatype == "nav_msgs/Odometry"   ? " (~motion_type odometry reads it)" :
                                                                       "";
    return "the motion topic " + topic + " carries " + info.datatype + ", not the " + expected + " ~motion_type " +
           motionTypeName(type) + " reads" + reads + ": no motion message can come";
  }
  return std::string();
}

std::string motionTypeName(MotionType type)
{
  switch (type)
  {
    case MotionType::kTwist:
      return "twist";
    case MotionType::kOdometry:
      return "odometry";
    case MotionType::kNone:
      break;
  }
  return "none";
}

MotionType readMotionType(const ros::NodeHandle& private_nh, MotionType fallback, std::string* problem)
{
  XmlRpc::XmlRpcValue value;
  if (!givenParameter(private_nh, "motion_type", &value, problem))
    return fallback;
  const std::string using_fallback = "; using " + motionTypeName(fallback);
  if (value.getType() != XmlRpc::XmlRpcValue::TypeString)
  {
    *problem = "~motion_type = " + parameterValueText(value) + " is not a string" + using_fallback;
    return fallback;
  }
  const std::string text = static_cast<std::string>(value);
  for (const MotionType type : { MotionType::kNone, MotionType::kTwist, MotionType::kOdometry })
    if (text == motionTypeName(type))
      return type;
  *problem = "~motion_type '" + text + "' is not one of none | twist | odometry" + using_fallback;
  return fallback;
}

bool readBoolParameter(const ros::NodeHandle& private_nh, const std::string& name, bool fallback, std::string* problem)
{
  XmlRpc::XmlRpcValue value;
  if (!givenParameter(private_nh, name, &value, problem))
    return fallback;
  switch (value.getType())
  {
    case XmlRpc::XmlRpcValue::TypeBoolean:
      return static_cast<bool>(value);
    case XmlRpc::XmlRpcValue::TypeInt:  // roslaunch types `value="0"` as an integer
      if (static_cast<int>(value) == 0 || static_cast<int>(value) == 1)
        return static_cast<int>(value) == 1;
      break;
    case XmlRpc::XmlRpcValue::TypeString:
    {
      std::string text = static_cast<std::string>(value);
      std::transform(text.begin(), text.end(), text.begin(), [](unsigned char c) { return std::tolower(c); });
      if (text == "true" || text == "1" || text == "yes" || text == "on")
        return true;
      if (text == "false" || text == "0" || text == "no" || text == "off")
        return false;
      break;
    }
    default:
      break;
  }
  *problem = "~" + name + " = " + parameterValueText(value) + " is not true or false; using " +
             (fallback ? "true" : "false");
  private_nh.setParam(name, fallback);
  return fallback;
}

int readIntParameter(const ros::NodeHandle& private_nh, const std::string& name, int fallback, std::string* problem)
{
  XmlRpc::XmlRpcValue value;
  if (!givenParameter(private_nh, name, &value, problem))
    return fallback;
  if (readableAsInt(value))
    return value.getType() == XmlRpc::XmlRpcValue::TypeInt ? static_cast<int>(value) :
                                                              static_cast<int>(static_cast<double>(value));
  *problem = mistypedSentence(name, value, "int", std::to_string(fallback));
  private_nh.setParam(name, fallback);
  return fallback;
}

double readDoubleParameter(const ros::NodeHandle& private_nh, const std::string& name, double fallback,
                           std::string* problem)
{
  XmlRpc::XmlRpcValue value;
  if (!givenParameter(private_nh, name, &value, problem))
    return fallback;
  if (value.getType() == XmlRpc::XmlRpcValue::TypeInt)
    return static_cast<int>(value);
  if (value.getType() == XmlRpc::XmlRpcValue::TypeDouble)
    return static_cast<double>(value);
  *problem = mistypedSentence(name, value, "double", numberText(fallback));
  private_nh.setParam(name, fallback);
  return fallback;
}

std::string readStringParameter(const ros::NodeHandle& private_nh, const std::string& name,
                                const std::string& fallback, std::string* problem)
{
  XmlRpc::XmlRpcValue value;
  if (!givenParameter(private_nh, name, &value, problem))
    return fallback;
  if (value.getType() == XmlRpc::XmlRpcValue::TypeString)
    return static_cast<std::string>(value);
  *problem = "~" + name + " = " + parameterValueText(value) + " is not a string; ignored";
  return fallback;
}

}  // namespace along_route_localization
