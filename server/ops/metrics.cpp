#include "server/ops/metrics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace vsurg::server::ops {
namespace {

std::string Number(double v) {
  if (std::isnan(v)) return "NaN";
  if (std::isinf(v)) return v > 0 ? "+Inf" : "-Inf";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

void AppendLabels(std::string& out, const Labels& labels) {
  if (labels.empty()) return;
  out += '{';
  for (size_t i = 0; i < labels.size(); ++i) {
    if (i) out += ',';
    out += labels[i].first;
    out += "=\"";
    for (char c : labels[i].second) {  // the format's three escapes
      if (c == '\\')
        out += "\\\\";
      else if (c == '"')
        out += "\\\"";
      else if (c == '\n')
        out += "\\n";
      else
        out += c;
    }
    out += '"';
  }
  out += '}';
}

}  // namespace

void MetricsText::Family(std::string_view name, std::string_view type, std::string_view help) {
  out_ += "# HELP ";
  out_ += name;
  out_ += ' ';
  for (char c : help) out_ += c == '\n' ? ' ' : c;  // (a backslash in help text: none of ours)
  out_ += "\n# TYPE ";
  out_ += name;
  out_ += ' ';
  out_ += type;
  out_ += '\n';
}

void MetricsText::Sample(std::string_view name, const Labels& labels, double value) {
  out_ += name;
  AppendLabels(out_, labels);
  out_ += ' ';
  out_ += Number(value);
  out_ += '\n';
}

void MetricsText::Histogram(std::string_view name, std::string_view help, const Labels& labels,
                            const std::vector<double>& bounds, const std::vector<double>& values) {
  // Each value in the first bucket whose bound it does not exceed (a NaN in none but +Inf).
  std::vector<uint64_t> counts(bounds.size() + 1, 0);
  double sum = 0;
  for (double v : values) {
    sum += v;
    const auto at =
        std::isnan(v) ? bounds.end() : std::lower_bound(bounds.begin(), bounds.end(), v);
    ++counts[static_cast<size_t>(at - bounds.begin())];
  }
  HistogramCounts(name, help, labels, bounds, counts, sum);
}

void MetricsText::HistogramCounts(std::string_view name, std::string_view help,
                                  const Labels& labels, const std::vector<double>& bounds,
                                  const std::vector<uint64_t>& counts, double sum) {
  Family(name, "histogram", help);
  const std::string bucket = std::string(name) + "_bucket";
  uint64_t cumulative = 0;
  for (size_t b = 0; b <= bounds.size(); ++b) {
    cumulative += b < counts.size() ? counts[b] : 0;
    Labels l = labels;
    l.emplace_back("le", b == bounds.size() ? "+Inf" : Number(bounds[b]));
    Sample(bucket, l, static_cast<double>(cumulative));
  }
  Sample(std::string(name) + "_sum", labels, sum);
  Sample(std::string(name) + "_count", labels, static_cast<double>(cumulative));
}

void MetricsRegistry::Add(Collector c) {
  std::lock_guard lock(mutex_);
  collectors_.push_back(std::move(c));
}

std::string MetricsRegistry::Render() const {
  std::lock_guard lock(mutex_);
  MetricsText t;
  for (const Collector& c : collectors_) c(t);
  return t.str();
}

}  // namespace vsurg::server::ops
