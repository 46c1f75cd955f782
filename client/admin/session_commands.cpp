// vsurg-admin scenes and sessions.
#include "client/admin/commands.h"

#include <openssl/evp.h>

#include <grpcpp/grpcpp.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/core/file.h"
#include "common/core/time.h"
#include "common/scoring/ratings_csv.h"
#include "common/scoring/report_json.h"
#include "db/vocabulary.h"
#include "proto/convert/services.h"
#include "vsurg/v1/services.grpc.pb.h"

namespace vsurg::admin {

namespace v1 = vsurg::v1;

// The scenes the server runs, and the sessions with the scoring loop's trial metrics.
int Scenes(const Args& args, std::ostream& out, std::ostream& err, const std::string& cmd) {
  ArgParser p("vsurg-admin " + cmd, cmd == "scenes"
                                        ? "Lists the scenes the server can run."
                                        : "Lists sessions with their trial metrics (ended ones).");
  if (cmd == "sessions") {
    p.Option("trainee", Kind::kString, "only this trainee's")
        .Option("json", Kind::kFlag, "one JSON object per line");
  }
  Remote remote;
  if (auto stop = Begin(p, args, out, err, remote)) return *stop;
  auto stub = v1::SessionService::NewStub(remote.channel);
  grpc::ClientContext ctx;
  remote.Prepare(ctx);
  if (cmd == "scenes") {
    v1::ListScenesResponse resp;
    const grpc::Status s = stub->ListScenes(&ctx, v1::ListScenesRequest(), &resp);
    if (!s.ok()) return RpcError(err, p.command(), s);
    out << "scene\tmodel\ttask\terror budget (RMS)\n";
    for (const v1::SceneInfo& i : resp.scenes())
      out << i.name() << "\t" << i.model() << "\t" << i.task() << "\t"
          << Fixed(i.error_budget_rms(), 2) << "\n";
    for (const std::string& why : resp.unusable()) err << "unusable scene file " << why << "\n";
    return 0;
  }
  v1::ListSessionsRequest req;
  if (p.Has("trainee")) req.set_trainee(p.String("trainee"));
  v1::ListSessionsResponse resp;
  const grpc::Status s = stub->List(&ctx, req, &resp);
  if (!s.ok()) return RpcError(err, p.command(), s);
  if (!p.Flag("json"))
    out << "id\ttrainee\tscene\tstate\tscore\tcompleted\ttime_s\ttask_error\tpeak_force_n\t"
           "over_limit_s\tpath_m\trms_jerk\toverloads\n";
  for (const v1::Session& x : resp.sessions()) {
    const v1::TrialMetrics& m = x.metrics();
    const std::string state = convert::StateName(x.state());
    if (p.Flag("json")) {
      nlohmann::json j = {{"id", x.id()},
                          {"trainee", x.trainee()},
                          {"scene", x.scene()},
                          {"state", state},
                          {"end_reason", x.end_reason()}};
      if (x.has_metrics()) j["metrics"] = scoring::TrialMetricsToJson(convert::FromProto(m));
      out << j.dump() << "\n";
      continue;
    }
    out << x.id() << "\t" << x.trainee() << "\t" << x.scene() << "\t" << state;
    if (x.has_metrics())
      out << "\t" << Fixed(m.score(), 1) << "\t" << (m.completed() ? "yes" : "no") << "\t"
          << Fixed(m.completion_time_s(), 2) << "\t" << Fixed(m.task_error(), 4) << "\t"
          << Fixed(m.peak_force_n(), 2) << "\t" << Fixed(m.time_over_force_limit_s(), 2) << "\t"
          << Fixed(m.path_length_m(), 3) << "\t" << Fixed(m.rms_jerk(), 0) << "\t"
          << m.overload_events();
    out << "\n";
  }
  return 0;
}

}  // namespace vsurg::admin
