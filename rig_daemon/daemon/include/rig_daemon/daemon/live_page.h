// The live page's HTML (rig_daemon/daemon/www/live.html), embedded into the daemon at build time so
// rigd serves it without any file next to the executable.
#pragma once

#include <string_view>

namespace hc::rig {

std::string_view live_page_html();

}  // namespace hc::rig
