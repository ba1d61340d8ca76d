#include "tests/testing/check_context.h"

#include "tests/testing/demo_site.h"

namespace roomfix::testing {

std::unique_ptr<ProcessContext> DemoCheckContext(const std::string& name, std::string* error) {
  auto ctx = std::make_unique<ProcessContext>();
  ctx->name = name;
  ctx->options.config_path = DemoSitePath();
  ctx->options.lcm_url = "memq://";
  ctx->options.check = true;
  if (!LoadSite(ctx->options.config_path, &ctx->site, error)) return nullptr;
  return ctx;
}

}  // namespace roomfix::testing
