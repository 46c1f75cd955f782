// The control plane's messages (vsurg/v1/services.proto) to and from the core's types: the one
// mapping of each type at the gRPC boundary, shared by the server's services and the clients.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "common/core/expected.h"
#include "common/core/session_state.h"
#include "common/haptics/blade.h"
#include "common/haptics/needle.h"
#include "common/haptics/tissue_surface.h"
#include "common/scoring/metrics.h"
#include "common/scoring/palpation.h"
#include "common/scoring/trial_metrics.h"
#include "common/sim/telemetry.h"
#include "vsurg/v1/services.pb.h"

namespace vsurg::convert {

// Same numbers on both sides (common/core/session_state.h); UNSPECIFIED and numbers a newer
// server may add are not a state.
v1::SessionState ToProto(SessionState s);
std::optional<SessionState> FromProto(v1::SessionState s);
// "running", "ended", … ("unspecified" for a state this client does not know).
std::string StateName(v1::SessionState s);

void ToProto(const scoring::TrialMetrics& m, v1::TrialMetrics* out);
scoring::TrialMetrics FromProto(const v1::TrialMetrics& m);

// A palpation's outcome; from the wire, lumps and marks that are not finite are left out and a
// mark's lump index out of range reads as a false mark (-1).
void ToProto(const scoring::PalpationOutcome& o, v1::PalpationOutcome* out);
scoring::PalpationOutcome FromProto(const v1::PalpationOutcome& o);

// An exercise's task settings; a kind other than twist or press reads as none given.
void ToProto(const scoring::TaskSettings& t, v1::TaskSettings* out);
scoring::TaskSettings FromProto(const v1::TaskSettings& t);

// A live session's sample (the surface's positions as floats on the wire). A state this side
// does not know reads as aborted.
void ToProto(const sim::SessionTelemetry& t, v1::Telemetry* out, bool with_surface = true);
sim::SessionTelemetry FromProto(const v1::Telemetry& t);

// The tissue's surface a station renders ahead of its tool. FromProto checks what a server sent
// as TissueSurface::Create does (bounds, indices, finite values): a refusal, never a surface
// that would render without bound.
void ToProto(const haptics::TissueSurface& s, v1::StationSurface* out);
// A needle scene's tissue, both ways; from the wire checked as a scene's is
// (haptics::CheckNeedleTissue): a refusal, never a model that renders out of its ranges.
void ToProto(const haptics::NeedleTissueSpec& s, v1::StationNeedle* out);
Expected<std::shared_ptr<const haptics::NeedleTissueSpec>> FromProto(const v1::StationNeedle& s);
// A cut scene's blade; FromProto checks it as the scene's was (haptics::CheckBlade).
void ToProto(const haptics::BladeParams& b, v1::StationBlade* out);
Expected<std::shared_ptr<const haptics::BladeParams>> FromProto(const v1::StationBlade& s);
Expected<std::shared_ptr<const haptics::TissueSurface>> FromProto(const v1::StationSurface& s);

}  // namespace vsurg::convert
