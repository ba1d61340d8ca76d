#ifndef ROOMFIX_TESTS_TESTING_CHECK_CONTEXT_H_
#define ROOMFIX_TESTS_TESTING_CHECK_CONTEXT_H_

// What StartProcess gives a process run as `NAME --config demo_room.yaml
// --lcm-url memq:// --check`, made without it (no logging set-up, no signal
// handlers, and, as with --check, no bus): for tests of a process's run
// function (sim/sim_app.h, zigbee_bridge/bridge_app.h) up to its check line.
#include <memory>
#include <string>

#include "msgio/process.h"

namespace roomfix::testing {

// nullptr with *error when the demo site does not load.
std::unique_ptr<ProcessContext> DemoCheckContext(const std::string& name, std::string* error);

}  // namespace roomfix::testing

#endif  // ROOMFIX_TESTS_TESTING_CHECK_CONTEXT_H_
