#ifndef ROOMFIX_TOOLS_TOOL_SITE_H_
#define ROOMFIX_TOOLS_TOOL_SITE_H_

#include <string>
#include <vector>

#include "msgio/site_message.h"

namespace roomfix {

// The site a tool uses for one log, as every tool says it on stderr
// (docs/analysis.md, "Which site"): --config when given (a warning naming the
// keys where the log's own site differs), otherwise the log's SITE; the
// log's refused SITE messages and disagreeing processes are warnings too.
struct ToolSite {
  bool known = false;
  LoadedSite site;
  // "log" or "--config".
  std::string source;
  // "site from LOG: ..." / "site from --config PATH: ...", or why unknown.
  std::string line;
  std::vector<std::string> warnings;
  // Why no site could be had (no SITE and no --config, or a bad --config).
  std::string error;
  // True when --config itself failed to load (always fatal).
  bool config_failed = false;
};

ToolSite ResolveSiteForLog(const std::string& config_path, const std::string& log_path);

// Prints the line and the warnings as "TOOL: LINE" and "TOOL: warning: W";
// an unknown site as "TOOL: note: site unknown: ERROR" when `required` is
// false, or as "TOOL: ERROR" when true. Returns false when the tool must stop:
// a required site is unknown, or --config failed.
bool ReportToolSite(const std::string& tool, const ToolSite& s, bool required);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_TOOL_SITE_H_
