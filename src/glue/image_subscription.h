// Subscribing to images through image_transport without letting a missing transport plugin end the manager.
#ifndef ALONG_ROUTE_LOCALIZATION_GLUE_IMAGE_SUBSCRIPTION_H
#define ALONG_ROUTE_LOCALIZATION_GLUE_IMAGE_SUBSCRIPTION_H

#include <stdexcept>
#include <string>

#include <image_transport/image_transport.h>
#include <ros/node_handle.h>
#include <sensor_msgs/Image.h>

namespace along_route_localization
{

/// The sentence for a subscription through the transport ~image_transport names (read from private_nh)
/// that image_transport could not set up (`what`: its exception's text, which lists the plugins it has).
std::string transportLoadSentence(const ros::NodeHandle& private_nh, const std::string& what);

/// "" when image_transport has the subscriber plugin of the transport ~image_transport names (default raw,
/// always there), else transportLoadSentence's sentence: checked when a nodelet is loaded, before it
/// subscribes (the preprocessor and the recorder subscribe only later).
std::string transportProblem(const ros::NodeHandle& private_nh);

/// it.subscribe(topic, ...) through the transport ~image_transport names (default raw). A transport whose
/// plugin is not installed (`compressed` without compressed_image_transport) throws out of image_transport,
/// and an exception out of a nodelet's callback or onInit ends the whole manager, camera driver included:
/// here it returns an empty subscriber instead, with *error saying which transport is missing and what to do.
template <class T>
image_transport::Subscriber subscribeTransported(image_transport::ImageTransport& it, const std::string& topic,
                                                 uint32_t queue_size,
                                                 void (T::*callback)(const sensor_msgs::ImageConstPtr&), T* object,
                                                 const ros::NodeHandle& private_nh, std::string* error)
{
  error->clear();
  try
  {
    const image_transport::TransportHints hints("raw", ros::TransportHints(), private_nh);
    return it.subscribe(topic, queue_size, callback, object, hints);
  }
  catch (const std::runtime_error& e)  // image_transport::TransportLoadException, pluginlib's
  {
    *error = transportLoadSentence(private_nh, e.what());
    return image_transport::Subscriber();
  }
}

}  // namespace along_route_localization

#endif  // ALONG_ROUTE_LOCALIZATION_GLUE_IMAGE_SUBSCRIPTION_H
