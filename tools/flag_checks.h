#ifndef ROOMFIX_TOOLS_FLAG_CHECKS_H_
#define ROOMFIX_TOOLS_FLAG_CHECKS_H_

#include <CLI/CLI.hpp>
#include <string>

namespace roomfix {

// CLI11 validators for numeric flags: a flag's value is refused while the
// command line is parsed, as "--flag: expected <what>" (command_line.cc
// prints it as the command's one-line refusal, exit 1). They exist beside
// CLI11's own Range and PositiveNumber because those let NaN through (every
// comparison with NaN is false) and take "inf"; these refuse both.

// A finite number above `min`.
CLI::Validator FiniteAbove(double min, const std::string& what);
// A finite number of at least `min`.
CLI::Validator FiniteAtLeast(double min, const std::string& what);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_FLAG_CHECKS_H_
