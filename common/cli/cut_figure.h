// The pattern-cutting drill's figure (cut_figure.cpp). Private to common/cli/.
#pragma once

#include <string>

#include "common/core/expected.h"
#include "common/sim/cut_drill.h"

namespace vsurg::cli {

// Writes DIR/cut.png (and its data and gnuplot script beside it).
Status WriteCutFigure(const std::string& dir, const sim::CutDrillSpec& spec,
                      const sim::CutDrillResult& r, const sim::CutDrillTrace& trace,
                      const std::string& hand);

}  // namespace vsurg::cli
