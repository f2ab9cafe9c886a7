#include "glue/reconfigure.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <ros/console.h>

namespace along_route_localization
{

namespace
{

/// Each parameter of a config message set in `params` through the parameter table, by name: no field is
/// mapped by hand here. A name that is not one of its choices leaves the field as it was, named in *problem.
ParameterSet fromMessage(const dynamic_reconfigure::Config& msg, ParameterSet params, std::string* problem)
{
  for (const dynamic_reconfigure::IntParameter& value : msg.ints)
    if (const ParameterSpec* spec = findParameter(value.name))
      spec->set_number(&params, value.value);
  for (const dynamic_reconfigure::DoubleParameter& value : msg.doubles)
    if (const ParameterSpec* spec = findParameter(value.name))
      spec->set_number(&params, value.value);
  for (const dynamic_reconfigure::BoolParameter& value : msg.bools)
    if (const ParameterSpec* spec = findParameter(value.name))
      spec->set_number(&params, value.value ? 1.0 : 0.0);
  for (const dynamic_reconfigure::StrParameter& value : msg.strs)
  {
    const ParameterSpec* spec = findParameter(value.name);
    if (spec && spec->type == ParameterType::kChoice && !spec->set_choice(&params, value.value) && problem)
      *problem = value.name + " '" + value.value + "' is not one of " + spec->rangeText();
  }
  return params;
}

template <class Config>
ParameterSet fromConfig(const Config& config, ParameterSet params, std::string* problem)
{
  dynamic_reconfigure::Config msg;
  config.__toMessage__(msg);
  return fromMessage(msg, params, problem);
}

}  // namespace

PreprocessingParams toParams(const PreprocessorConfig& config, std::string* problem)
{
  return fromConfig(config, ParameterSet(), problem).preprocessing;
}

LocalizerParams toParams(const LocalizerConfig& config, LocalizerParams base, std::string* problem)
{
  ParameterSet params;
  params.localizer = base;
  return fromConfig(config, params, problem).localizer;
}

KeyframePolicy toPolicy(const MapRecorderConfig& config)
{
  return fromConfig(config, ParameterSet(), nullptr).keyframes;
}

RouteFollowerParams toParams(const RouteFollowerConfig& config)
{
  return fromConfig(config, ParameterSet(), nullptr).follower;
}

namespace
{

std::string text(double value)
{
  char buffer[64];
  std::snprintf(buffer, sizeof(buffer), "%.6g", value);
  return buffer;
}

}  // namespace

std::vector<std::string> correctToTable(dynamic_reconfigure::Config* msg, const dynamic_reconfigure::Config& previous)
{
  std::vector<std::string> corrections;
  const auto number = [&](const std::string& name, double given, double before, double* used) {
    const ParameterSpec* spec = findParameter(name);
    if (!spec)
      return;
    const std::string sentence = correctNumber(*spec, given, before, used);
    if (!sentence.empty())
      corrections.push_back(sentence);
  };
  for (dynamic_reconfigure::IntParameter& value : msg->ints)
  {
    const dynamic_reconfigure::IntParameter* before = findByName(previous.ints, value.name);
    double used = value.value;
    number(value.name, value.value, before ? before->value : value.value, &used);
    value.value = static_cast<int>(used);
  }
  for (dynamic_reconfigure::DoubleParameter& value : msg->doubles)
  {
    const dynamic_reconfigure::DoubleParameter* before = findByName(previous.doubles, value.name);
    number(value.name, value.value, before ? before->value : value.value, &value.value);
  }
  for (dynamic_reconfigure::StrParameter& value : msg->strs)
  {
    const ParameterSpec* spec = findParameter(value.name);
    const dynamic_reconfigure::StrParameter* before = findByName(previous.strs, value.name);
    if (!spec || spec->type != ParameterType::kChoice || !before ||
        std::find(spec->choices.begin(), spec->choices.end(), value.value) != spec->choices.end())
      continue;
    corrections.push_back(value.name + " '" + value.value + "' is not one of " + spec->rangeText() + "; keeping " +
                          before->value);
    value.value = before->value;
  }
  return corrections;
}

std::vector<std::string> configChanges(const dynamic_reconfigure::Config& before, const dynamic_reconfigure::Config& after)
{
  std::vector<std::string> changes;
  for (const dynamic_reconfigure::IntParameter& value : after.ints)
    if (const dynamic_reconfigure::IntParameter* old = findByName(before.ints, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + std::to_string(old->value) + " -> " + std::to_string(value.value));
  for (const dynamic_reconfigure::DoubleParameter& value : after.doubles)
    if (const dynamic_reconfigure::DoubleParameter* old = findByName(before.doubles, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + text(old->value) + " -> " + text(value.value));
  for (const dynamic_reconfigure::StrParameter& value : after.strs)
    if (const dynamic_reconfigure::StrParameter* old = findByName(before.strs, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + old->value + " -> " + value.value);
  for (const dynamic_reconfigure::BoolParameter& value : after.bools)
    if (const dynamic_reconfigure::BoolParameter* old = findByName(before.bools, value.name))
      if (old->value != value.value)
        changes.push_back(value.name + " " + (old->value ? "true" : "false") + " -> " + (value.value ? "true" : "false"));
  return changes;
}

void logConfigReview(const ConfigReview& review, const std::string& logger, const std::string& what)
{
  for (const std::string& correction : review.corrections)
    ROS_WARN_NAMED(logger, "%s", correction.c_str());
  if (!review.rejected.empty())
    ROS_ERROR_NAMED(logger, "Rejected %s: %s; keeping the previous ones", what.c_str(), review.rejected.c_str());
  for (const std::string& change : review.changes)
    ROS_INFO_NAMED(logger, "%s", change.c_str());
}

}  // namespace along_route_localization
