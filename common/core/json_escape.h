// Text as the inside of a JSON string, for the places that write JSON by hand because they stream
// it (the exports, a million rows without a document in memory; the event log, one line at a
// time on any thread).
#pragma once

#include <string>
#include <string_view>

namespace vsurg {

// Appends `s` with quotes, backslashes and control characters escaped (UTF-8 passes as is).
void AppendJsonEscaped(std::string& out, std::string_view s);

}  // namespace vsurg
