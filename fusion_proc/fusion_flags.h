#ifndef ROOMFIX_FUSION_PROC_FUSION_FLAGS_H_
#define ROOMFIX_FUSION_PROC_FUSION_FLAGS_H_

#include <CLI/CLI.hpp>
#include <string>

#include "fusion_proc/fusion_node.h"

namespace roomfix {

// fusion_proc's flags (channels, rate, forgetting, the filter's noise,
// gates and history), shared with `roomfix replay` so a log recorded with
// non-default settings is re-run with the same ones. Each is named
// `prefix` + the name after "--" (prefix "" for fusion_proc, "fusion-" in
// the replay, where trilat_proc's --forget-after is also taken).
void AddFusionFlags(CLI::App* app, const std::string& prefix, FusionNodeOptions* options);

}  // namespace roomfix

#endif  // ROOMFIX_FUSION_PROC_FUSION_FLAGS_H_
