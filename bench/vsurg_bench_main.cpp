// vsurg-bench: whole-system measurements (micro-benchmarks are in vsurg-microbench).
//
//   vsurg-bench haptic-rtt --stations N --seconds S [--scene arm-torsion] [--idle N
//                          [--idle-scene NAME] [--idle-threads]] [--busy-poll-us U] [--json]
//     N simulated stations at 1 kHz against a real UDP endpoint on loopback, each with its own
//     session and simulation (deformation thread included); prints rtt_p50_us, rtt_p99_us,
//     rtt_p999_us, loss and server_cpu_per_station (the endpoint I/O thread's CPU time per
//     station, as a fraction of one core), and with --json the node's share of the round trip
//     (server_residence_*: each answer's time from its datagram's arrival to its send).
//     --stations-per-socket K: the driver's stations share sockets, K to a batch (both commands).
//
//   vsurg-bench udp-floor --stations N --seconds S [--realtime-priority P] [--busy-poll-us U]
//                         [--batch B] [--json]
//     the floor under haptic-rtt: the same stations, pacing and statistics against a plain UDP
//     echo (one thread, a blocking socket); report haptic-rtt's figures as ratios to it. With
//     --busy-poll-us the echo polls before it blocks, by the endpoint's rule (for comparison);
//     with --batch B it takes up to B datagrams a recvmmsg and answers them in one sendmmsg.
//     Both print the CPU per answered datagram (server_*cpu_per_datagram_us).
//
//   vsurg-bench grpc-submit [--clients 32] [--seconds 5] [--batches 1,1024] [--json]
//     durable evaluation submissions per second through gRPC, per writer batch limit.
//   vsurg-bench export [--rows 1000000] [--format csv] [--json]
//     export of N evaluation rows from the store and streamed through gRPC.
//   vsurg-bench fem-step [--rings 5] [--steps 50] [--tolerance 1e-4] [--export DIR] [--json]
//     one corotational implicit FEM step on BM_FemStep's twisted bar (fem_step_command.h); with
//     --export, the bar written as files VegaFEM reads (bench/peers/fem.sh).
//   vsurg-bench hyper-step [--rings 4] [--steps 20] [--tolerance 1e-6] [--export DIR] [--json]
//     one implicit-Euler step of the neo-Hookean FEM on that bar twisted harder (bench/peers/
//     hyper.sh runs VegaFEM's beside it).
//   vsurg-bench speed-vs-error [--quick] [--out docs]
//     every model against the same references: time per update vs marker error (see
//     speed_vs_error.h).
#include <exception>
#include <iostream>
#include <string>
#include <vector>

#include "bench/control_bench.h"
#include "bench/fem_step_command.h"
#include "bench/msm_step_command.h"
#include "bench/rtt_commands.h"
#include "bench/speed_vs_error.h"

namespace vsurg::bench {
int Wan(const std::vector<std::string>& args);        // bench/wan/wan_command.cpp
int FourHands(const std::vector<std::string>& args);  // bench/wan/four_hands_command.cpp
}  // namespace vsurg::bench

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  if (args.empty() || args[0] == "--help") {
    std::cout << "usage: vsurg-bench haptic-rtt --stations N --seconds S [--scene NAME] [--idle N "
                 "[--idle-scene NAME] [--idle-threads]] [--dashboard-clients N] [--json]\n"
                 "       vsurg-bench udp-floor --stations N --seconds S [--json]\n"
                 "       vsurg-bench grpc-submit [--clients N] [--seconds S] [--batches 1,1024] "
                 "[--postgres URI]\n"
                 "       vsurg-bench placement --postgres URI [--nodes 3] [--sessions 60]\n"
                 "       vsurg-bench heartbeats --postgres URI [--nodes 1000] [--seconds 15]\n"
                 "       vsurg-bench telemetry --postgres URI [--nodes 3] [--sessions 8]\n"
                 "       vsurg-bench msm-step [--steps 2000] [--export DIR] [--json]\n"
                 "       vsurg-bench export [--rows N] [--format csv|jsonl|xapi]\n"
                 "       vsurg-bench speed-vs-error [--quick] [--out DIR]\n"
                 "       vsurg-bench fem-step [--rings 5] [--steps 50] [--tolerance 1e-4] "
                 "[--export DIR] [--json]\n"
                 "       vsurg-bench hyper-step [--rings 4] [--steps 20] [--tolerance 1e-6] "
                 "[--export DIR] [--json]\n"
                 "       vsurg-bench wan [--profiles P,..] [--scenes S,..] [--methods "
                 "server,linear,model] [--grip tensed] [--runs N] [--out DIR]\n"
                 "       vsurg-bench four-hands [--profiles P,..] [--scene S] [--out DIR]\n";
    return args.empty() ? 2 : 0;
  }
  try {
    if (args[0] == "haptic-rtt") return vsurg::bench::HapticRtt({args.begin() + 1, args.end()});
    if (args[0] == "udp-floor") return vsurg::bench::UdpFloor({args.begin() + 1, args.end()});
    if (args[0] == "grpc-submit") return vsurg::bench::GrpcSubmit({args.begin() + 1, args.end()});
    if (args[0] == "msm-step") return vsurg::bench::MsmStep({args.begin() + 1, args.end()});
    if (args[0] == "placement") return vsurg::bench::Placement({args.begin() + 1, args.end()});
    if (args[0] == "heartbeats") return vsurg::bench::Heartbeats({args.begin() + 1, args.end()});
    if (args[0] == "telemetry") return vsurg::bench::TelemetryBench({args.begin() + 1, args.end()});
    if (args[0] == "export") return vsurg::bench::ExportBench({args.begin() + 1, args.end()});
    if (args[0] == "speed-vs-error")
      return vsurg::bench::SpeedVsError({args.begin() + 1, args.end()});
    if (args[0] == "fem-step") return vsurg::bench::FemStep({args.begin() + 1, args.end()});
    if (args[0] == "hyper-step") return vsurg::bench::HyperStep({args.begin() + 1, args.end()});
    if (args[0] == "wan") return vsurg::bench::Wan({args.begin() + 1, args.end()});
    if (args[0] == "four-hands") return vsurg::bench::FourHands({args.begin() + 1, args.end()});
  } catch (const std::exception& e) {
    std::cerr << "vsurg-bench: " << e.what() << "\n";
    return 1;
  }
  std::cerr << "vsurg-bench: unknown command '" << args[0]
            << "' (haptic-rtt, udp-floor, grpc-submit, placement, heartbeats, telemetry, msm-step, "
               "export, "
               "speed-vs-error, "
               "fem-step, hyper-step, wan, four-hands)\n";
  return 2;
}
