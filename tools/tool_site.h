#ifndef ROOMFIX_TOOLS_TOOL_SITE_H_
#define ROOMFIX_TOOLS_TOOL_SITE_H_

#include <string>

#include "msgio/site_message.h"

namespace roomfix {

// Prints the site a tool resolved (ResolveToolSite, msgio/site_message.h):
// the line and the warnings as "TOOL: LINE" and "TOOL: warning: W"; an
// unknown site as "TOOL: note: site unknown: ERROR" when `required` is
// false, or as "TOOL: ERROR" when true. Returns false when the tool must stop:
// a required site is unknown, or --config failed.
bool ReportToolSite(const std::string& tool, const ToolSite& s, bool required);

}  // namespace roomfix

#endif  // ROOMFIX_TOOLS_TOOL_SITE_H_
