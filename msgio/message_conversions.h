#ifndef ROOMFIX_MSGIO_MESSAGE_CONVERSIONS_H_
#define ROOMFIX_MSGIO_MESSAGE_CONVERSIONS_H_

// The one conversion per message type between msgio/messages.h's structs and
// the generated types. ToMessage copies every field and sets the counts from
// the vectors; FromMessage copies every field of a message DecodeChecked
// accepted, whose enum fields it has checked to hold one of their .lcm
// constants (wire_check.h: enum_out_of_range), so each casts to a named
// enumerator. Neither checks other values: a producer states what it
// measured, a consumer refuses what it cannot use.

#include "msgio/messages.h"
#include "roomfix/detector_view_request_t.hpp"
#include "roomfix/detector_view_t.hpp"
#include "roomfix/image_t.hpp"
#include "roomfix/marker_pixels_t.hpp"
#include "roomfix/pose2d_t.hpp"

namespace roomfix {

pose2d_t ToMessage(const Pose2d& pose);
Pose2d FromMessage(const pose2d_t& msg);

marker_pixels_t ToMessage(const MarkerPixels& pixels);
MarkerPixels FromMessage(const marker_pixels_t& msg);

image_t ToMessage(const PreviewImage& image);
PreviewImage FromMessage(const image_t& msg);

detector_view_t ToMessage(const DetectorViewImage& view);
DetectorViewImage FromMessage(const detector_view_t& msg);

detector_view_request_t ToMessage(const DetectorViewRequest& request);
DetectorViewRequest FromMessage(const detector_view_request_t& msg);

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_MESSAGE_CONVERSIONS_H_
