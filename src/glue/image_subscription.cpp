#include "glue/image_subscription.h"

#include <image_transport/subscriber_plugin.h>
#include <pluginlib/class_loader.hpp>

namespace along_route_localization
{

namespace
{

/// The transport ~image_transport names (as TransportHints reads it), raw by default.
std::string chosenTransport(const ros::NodeHandle& private_nh)
{
  std::string transport = "raw";
  private_nh.getParam("image_transport", transport);
  return transport;
}

}  // namespace

std::string transportProblem(const ros::NodeHandle& private_nh)
{
  const std::string transport = chosenTransport(private_nh);
  if (transport == "raw")
    return std::string();
  // As image_transport looks its subscriber plugins up: "image_transport/<name>_sub".
  const std::string lookup = "image_transport/" + transport + "_sub";
  try
  {
    pluginlib::ClassLoader<image_transport::SubscriberPlugin> loader("image_transport",
                                                                     "image_transport::SubscriberPlugin");
    if (loader.isClassAvailable(lookup))
      return std::string();
    std::string declared;
    for (const std::string& name : loader.getDeclaredClasses())
      declared += (declared.empty() ? "" : ", ") + name;
    return transportLoadSentence(private_nh, "no " + lookup + "; declared: " + declared);
  }
  catch (const std::runtime_error& e)  // pluginlib's
  {
    return transportLoadSentence(private_nh, e.what());
  }
}

std::string transportLoadSentence(const ros::NodeHandle& private_nh, const std::string& what)
{
  return "~image_transport '" + chosenTransport(private_nh) + "' cannot be used: image_transport cannot load its plugin (" + what +
         "). Install it (for compressed: " +
         "ros-noetic-compressed-image-transport, in image_transport_plugins) or set ~image_transport to raw, then " +
         "load this nodelet again; no images are taken until then";
}

}  // namespace along_route_localization
