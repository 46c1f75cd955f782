// Operations: the Prometheus text exposition format (version 0.0.4) and a registry of collectors
// that each role fills at a scrape (a site operator's view). Written here rather
// than taken from prometheus-cpp: Debian does not package it, and what we need is a text writer
// of a few families (counters, gauges, histograms) computed at scrape time from figures the
// server already keeps, with no metric objects on the haptic path.
//
// Thread safety: MetricsRegistry::Add and Render from any thread; collectors run on the caller
// of Render, one at a time.
#pragma once

#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace vsurg::server::ops {

using Labels = std::vector<std::pair<std::string, std::string>>;

class MetricsText {
 public:
  // A family's HELP and TYPE lines (type: counter, gauge, histogram), once before its samples.
  void Family(std::string_view name, std::string_view type, std::string_view help);
  // One sample: `name{labels} value` (label values escaped; NaN and infinities as Prometheus
  // spells them).
  void Sample(std::string_view name, const Labels& labels, double value);
  // A histogram family of `values` over the upper `bounds` (ascending; +Inf is added):
  // cumulative _bucket samples, _sum and _count.
  void Histogram(std::string_view name, std::string_view help, const Labels& labels,
                 const std::vector<double>& bounds, const std::vector<double>& values);
  // The same from counts kept as they came: counts[b] observations at most bounds[b] and above
  // bounds[b-1] (counts has one more entry than bounds: above every bound), their `sum`.
  void HistogramCounts(std::string_view name, std::string_view help, const Labels& labels,
                       const std::vector<double>& bounds, const std::vector<uint64_t>& counts,
                       double sum);
  const std::string& str() const { return out_; }

 private:
  std::string out_;
};

class MetricsRegistry {
 public:
  using Collector = std::function<void(MetricsText&)>;
  void Add(Collector c);
  std::string Render() const;  // every collector, in the order added

 private:
  mutable std::mutex mutex_;
  std::vector<Collector> collectors_;
};

}  // namespace vsurg::server::ops
