#include "common/core/args.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <ostream>
#include <sstream>

namespace vsurg::cli {
namespace {

bool ToDouble(const std::string& s, double& out) {
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, out);
  return !s.empty() && ec == std::errc() && ptr == end && std::isfinite(out);
}

bool ToInt(const std::string& s, int& out) {
  const char* end = s.data() + s.size();
  auto [ptr, ec] = std::from_chars(s.data(), end, out);
  return !s.empty() && ec == std::errc() && ptr == end;
}

// CLI11's own refusal (an option given without its value): "--dt: 1 required TEXT missing" is
// named by the option it starts with.
Status CliError(const std::string& what) {
  const size_t colon = what.find(':');
  if (what.rfind("--", 0) == 0 && colon != std::string::npos) {
    return InvalidArgument(what.substr(0, colon), "needs a value");
  }
  return InvalidArgument("arguments", what);
}

}  // namespace

ArgParser::ArgParser(std::string command, std::string summary)
    : command_(std::move(command)), summary_(std::move(summary)) {}

ArgParser& ArgParser::Option(const std::string& name, Kind kind, const std::string& help,
                             bool required, const std::string& default_value) {
  order_.push_back(name);
  specs_[name] = Spec{kind, help, required, default_value, std::nullopt};
  return *this;
}

ArgParser& ArgParser::Within(Range r) {
  specs_.at(order_.back()).range = r;
  return *this;
}

// The tokens are CLI11's to split (`--name value`, `--name=value`, flags, what is left over); the
// values' rules (finite numbers, whole tokens, ranges, non-empty strings) and the errors' wording
// are the tools' own, so that every error names its option in one form.
Status ArgParser::Parse(const std::vector<std::string>& args) {
  values_.clear();
  help_ = std::find(args.begin(), args.end(), "--help") != args.end() ||
          std::find(args.begin(), args.end(), "-h") != args.end();
  if (help_) return Status::Ok();
  CLI::App app{summary_, command_};
  app.set_help_flag();
  app.allow_extras(true);
  std::map<std::string, CLI::Option*> given;
  for (const std::string& name : order_) {
    CLI::Option* o =
        specs_[name].kind == Kind::kFlag ? app.add_flag("--" + name) : app.add_option("--" + name);
    given[name] = o->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  }
  std::vector<std::string> reversed(args.rbegin(), args.rend());  // CLI11 pops from the back
  try {
    app.parse(reversed);
  } catch (const CLI::ParseError& e) {
    return CliError(e.what());
  }
  if (Status left = LeftOver(app.remaining()); !left.ok()) return left;
  for (const std::string& name : order_) {
    if (Status s = Take(name, given[name]->results()); !s.ok()) return s;
  }
  return Status::Ok();
}

// The first token no option took: an option nobody declared, or a stray word.
Status ArgParser::LeftOver(const std::vector<std::string>& remaining) const {
  if (remaining.empty()) return Status::Ok();
  const std::string& a = remaining.front();
  if (a.rfind("--", 0) == 0 && a.size() > 2) {
    return InvalidArgument(a.substr(0, a.find('=')), "unknown option (see --help)");
  }
  return InvalidArgument(a, "unexpected argument '" + a + "' (options start with --)");
}

// One option's values as CLI11 found them, checked by its kind and range.
Status ArgParser::Take(const std::string& name, const std::vector<std::string>& results) {
  const Spec& spec = specs_.at(name);
  const std::string field = "--" + name;
  if (results.empty()) {
    return spec.required ? InvalidArgument(field, "is required (see --help)") : Status::Ok();
  }
  if (results.size() > 1) return InvalidArgument(field, "given more than once");
  const std::string& value = results.front();
  if (spec.kind == Kind::kFlag) {
    if (value != "true") return InvalidArgument(field, "takes no value");
    values_[name] = "1";
    return Status::Ok();
  }
  if (spec.kind == Kind::kDouble) {
    double d;
    if (!ToDouble(value, d))
      return InvalidArgument(field, "'" + value + "' is not a finite number");
    if (spec.range && !spec.range->Contains(d)) return InvalidArgument(field, spec.range->Must());
  } else if (spec.kind == Kind::kInt) {
    int n;
    if (!ToInt(value, n)) return InvalidArgument(field, "'" + value + "' is not an integer");
    if (spec.range && !spec.range->Contains(n)) return InvalidArgument(field, spec.range->Must());
  } else if (value.empty()) {
    return InvalidArgument(field, "needs a non-empty value");
  }
  values_[name] = value;
  return Status::Ok();
}

bool ArgParser::Has(const std::string& name) const {
  return values_.count(name) > 0;
}

std::string ArgParser::String(const std::string& name) const {
  const auto it = values_.find(name);
  return it != values_.end() ? it->second : specs_.at(name).default_value;
}

std::vector<std::string> ArgParser::List(const std::string& name) const {
  std::vector<std::string> out;
  const std::string all = String(name);
  for (size_t start = 0; start <= all.size();) {
    size_t end = all.find(',', start);
    if (end == std::string::npos) end = all.size();
    if (end > start) out.push_back(all.substr(start, end - start));
    start = end + 1;
  }
  return out;
}

double ArgParser::Double(const std::string& name) const {
  double d = 0;
  ToDouble(String(name), d);
  return d;
}

int ArgParser::Int(const std::string& name) const {
  int n = 0;
  ToInt(String(name), n);
  return n;
}

std::string ArgParser::Help() const {
  std::ostringstream out;
  out << "usage: " << command_;
  for (const std::string& name : order_) {
    const Spec& s = specs_.at(name);
    std::string arg = "--" + name + (s.kind == Kind::kFlag ? "" : " X");
    out << ' ' << (s.required ? arg : "[" + arg + "]");
  }
  out << "\n\n" << summary_ << "\n\noptions:\n";
  for (const std::string& name : order_) {
    const Spec& s = specs_.at(name);
    out << "  --" << name;
    for (size_t pad = name.size(); pad < 16; ++pad) out << ' ';
    out << ' ' << s.help;
    if (!s.default_value.empty()) out << " (default " << s.default_value << ")";
    if (s.range) out << " (within " << s.range->Text() << ")";
    if (s.required) out << " (required)";
    out << '\n';
  }
  out << "  --help             this help\n";
  return out.str();
}

int UsageError(std::ostream& err, const std::string& command, const Error& e) {
  err << command << ": " << (e.field.empty() ? "" : e.field + ": ") << e.message << "\n";
  return kExitUsage;
}

std::optional<int> ParseOrExit(ArgParser& p, const std::vector<std::string>& args,
                               std::ostream& out, std::ostream& err) {
  if (Status s = p.Parse(args); !s.ok()) return UsageError(err, p.command(), s.error());
  if (p.HelpRequested()) {
    out << p.Help();
    return 0;
  }
  return std::nullopt;
}

}  // namespace vsurg::cli
