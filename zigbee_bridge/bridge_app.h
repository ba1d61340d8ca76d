#ifndef ROOMFIX_ZIGBEE_BRIDGE_BRIDGE_APP_H_
#define ROOMFIX_ZIGBEE_BRIDGE_BRIDGE_APP_H_

// zigbee_bridge around its node: the coordinator's part of the site, the
// serial port kept open, the read loop that stamps each read, and the
// closing counts. zigbee_bridge_main.cc is its flags and a call to these.

#include <string>

#include "msgio/process.h"
#include "zigbee_bridge/bridge_node.h"
#include "zigbee_bridge/serial_link.h"

namespace roomfix {

// What zigbee_bridge's flags choose.
struct BridgeAppOptions {
  BridgeNodeOptions node;
  SerialLinkOptions link;
  // The coordinator this bridge reads (site radios[].id); 0: the site has
  // one coordinator for every receiver.
  int radio_id = 0;
  // Stop after this long (0: until a signal).
  double duration_s = 0.0;

  // False with the node's or the serial link's reason (a deadline out of
  // range, a baud rate that is not a standard UART rate, ...).
  bool IsValid(std::string* error) const;
};

// Runs the bridge on a started process (ctx->site, ctx->bus): with radio_id,
// only that coordinator's receivers are expected (1 with "--radio: ..." in
// *error when the site names no such radio); without it a site of several
// radios is a warning. With ctx->options.check prints the one line
// "zigbee_bridge: ok: ..." and returns 0. Otherwise reads the port until a
// signal or the duration, reopening it whenever it fails, and returns
// RunLoop's status.
int RunBridge(ProcessContext* ctx, const BridgeAppOptions& options, std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_ZIGBEE_BRIDGE_BRIDGE_APP_H_
