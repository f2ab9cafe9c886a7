#include "ros/private_parameters.h"

#include <algorithm>
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

std::string outOfRangeSentence(const std::string& name, double value, double lo, double hi)
{
  std::ostringstream text;
  text << "~" << name << " = " << value << " is outside " << lo << " .. " << hi;
  if (value < lo || value > hi)
    text << "; dynamic_reconfigure uses " << (value < lo ? lo : hi) << " instead";
  return text.str();
}

std::string joined(const std::set<std::string>& names)
{
  std::string text;
  for (const std::string& name : names)
    text += (text.empty() ? "" : ", ") + name;
  return text;
}

}  // namespace along_route_localization
