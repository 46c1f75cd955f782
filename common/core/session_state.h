// A session's state: the one vocabulary of the session manager, the UDP endpoint's events, the
// store (as text), the wire (vsurg.v1.SessionState, same numbers) and the clients.
//
//   created ──Start──▶ running ◀──stylus again──▶ stalled
//   created/running/stalled ──Stop──▶ ended, ──no stylus 5 s──▶ disconnected, ──▶ aborted
//
// (the full transition table: server/session/session_manager.h). The numbers are the wire's and
// the names are the store's: neither is ever renumbered or respelled.
#pragma once

#include <cstdint>
#include <optional>
#include <string_view>

namespace vsurg {

enum class SessionState : uint8_t {
  kCreated = 1,       // key handed out, not started
  kRunning = 2,       // started; stylus data arriving
  kStalled = 3,       // no stylus data for 0.5 s
  kEnded = 4,         // stopped
  kDisconnected = 5,  // no stylus data for 5 s
  kAborted = 6,       // never started in time, access revoked, or the server shut down
};

inline constexpr const char* kSessionStateNames[] = {"created", "running",      "stalled",
                                                     "ended",   "disconnected", "aborted"};

inline constexpr const char* SessionStateName(SessionState s) {
  const int i = static_cast<int>(s) - 1;
  return i >= 0 && i < 6 ? kSessionStateNames[i] : "unknown";
}

inline std::optional<SessionState> ParseSessionState(std::string_view name) {
  for (int i = 0; i < 6; ++i)
    if (name == kSessionStateNames[i]) return static_cast<SessionState>(i + 1);
  return std::nullopt;
}

// The wire's number (vsurg.v1.SessionState); 0 and unknown numbers are not a state.
inline constexpr std::optional<SessionState> SessionStateFromNumber(int n) {
  if (n < 1 || n > 6) return std::nullopt;
  return static_cast<SessionState>(n);
}

// Created, running or stalled: the session holds a simulation and can still change.
inline constexpr bool IsLive(SessionState s) {
  return s == SessionState::kCreated || s == SessionState::kRunning || s == SessionState::kStalled;
}

}  // namespace vsurg
