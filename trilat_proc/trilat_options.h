#ifndef ROOMFIX_TRILAT_PROC_TRILAT_OPTIONS_H_
#define ROOMFIX_TRILAT_PROC_TRILAT_OPTIONS_H_

#include <CLI/CLI.hpp>
#include <string>

#include "trilat_proc/trilat_node.h"

namespace roomfix {

// trilat_proc's solver flags, shared with `roomfix replay` so a log recorded
// with non-default settings is re-run with the same ones. The strings are
// turned into options by ApplyTrilatFlags after parsing.
struct TrilatOptions {
  // The --method default shown in the help (trilat_proc: "default"; the
  // replay: "robust", which every shipped configuration runs).
  std::string method = "default";
  std::string dimension = "fixed-height";
  bool no_prior = false;
  bool no_nlos_belief = false;
};

// Adds --method, --dimension, --range-sigma, --outlier-threshold,
// --warm-start-max-age, --forget-after, --unknown-beacon-height,
// --no-prior and --prior-reset-after, each named `prefix` + the name after
// "--" (prefix "" for trilat_proc).
void AddTrilatFlags(CLI::App* app, const std::string& prefix, TrilatNodeOptions* options,
                    TrilatOptions* flags);

// The parsed strings into *options; false with one line for a name
// AddTrilatFlags' checks would refuse.
bool ApplyTrilatFlags(const TrilatOptions& flags, TrilatNodeOptions* options, std::string* error);

}  // namespace roomfix

#endif  // ROOMFIX_TRILAT_PROC_TRILAT_OPTIONS_H_
