#include "common/core/args.h"

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

Status ArgParser::Parse(const std::vector<std::string>& args) {
  values_.clear();
  help_ = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const std::string& a = args[i];
    if (a == "--help" || a == "-h") {
      help_ = true;
      return Status::Ok();
    }
    if (a.rfind("--", 0) != 0 || a.size() == 2) {
      return InvalidArgument(a, "unexpected argument '" + a + "' (options start with --)");
    }
    std::string name = a.substr(2), value;
    bool inline_value = false;
    if (const size_t eq = name.find('='); eq != std::string::npos) {
      value = name.substr(eq + 1);
      name = name.substr(0, eq);
      inline_value = true;
    }
    const auto it = specs_.find(name);
    if (it == specs_.end()) return InvalidArgument("--" + name, "unknown option (see --help)");
    if (values_.count(name)) return InvalidArgument("--" + name, "given more than once");
    const Spec& spec = it->second;
    if (spec.kind == Kind::kFlag) {
      if (inline_value) return InvalidArgument("--" + name, "takes no value");
      values_[name] = "1";
      continue;
    }
    if (!inline_value) {
      if (i + 1 >= args.size()) return InvalidArgument("--" + name, "needs a value");
      value = args[++i];
    }
    if (spec.kind == Kind::kDouble) {
      double d;
      if (!ToDouble(value, d))
        return InvalidArgument("--" + name, "'" + value + "' is not a finite number");
      if (spec.range && !spec.range->Contains(d))
        return InvalidArgument("--" + name, spec.range->Must());
    } else if (spec.kind == Kind::kInt) {
      int n;
      if (!ToInt(value, n))
        return InvalidArgument("--" + name, "'" + value + "' is not an integer");
      if (spec.range && !spec.range->Contains(n))
        return InvalidArgument("--" + name, spec.range->Must());
    } else if (value.empty()) {
      return InvalidArgument("--" + name, "needs a non-empty value");
    }
    values_[name] = value;
  }
  for (const std::string& name : order_) {
    if (specs_[name].required && !values_.count(name)) {
      return InvalidArgument("--" + name, "is required (see --help)");
    }
  }
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
