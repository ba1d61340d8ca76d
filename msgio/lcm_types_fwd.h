#ifndef ROOMFIX_MSGIO_LCM_TYPES_FWD_H_
#define ROOMFIX_MSGIO_LCM_TYPES_FWD_H_

// Forward declarations of the generated message types (lcmtypes/*.lcm).
// A node's header names a message type only here, by reference (the
// subscription callbacks it exposes for tests and replay), so that what
// includes the header does not see the generated code; the node's .cc
// includes the generated header it subscribes to, and fills a message only
// through msgio's conversions (docs/development.md, "Layout").

namespace roomfix {

class counter_t;
class detector_view_request_t;
class detector_view_robot_t;
class detector_view_t;
class image_t;
class marker_pixels_t;
class marker_t;
class pose2d_t;
class process_status_t;
class range_set_t;
class range_t;
class site_file_t;
class site_t;

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_LCM_TYPES_FWD_H_
