// Mutual TLS on the internal API: a node's name bound to its certificate, only the site's
// certificates, renewals without a restart.
#include "tests/server/cluster/cluster_fixture.h"

namespace vsurg::server::cluster {
namespace {

using namespace test_cluster;  // NOLINT: the suites' fixture and helpers

// --- Mutual TLS on the internal API (docs/SCALING.md, "Mutual TLS") ---

// Certificates from deploy/cluster_certs.sh: a site CA ("site") naming vsurg-control, sim-a and
// sim-b, and a stranger's CA ("other") naming the same.
class ClusterTlsTest : public ClusterTest {
 protected:
  void Configure() override {
    for (const char* ca : {"site", "other"}) {
      const std::string cmd = std::string(VSURG_SOURCE_DIR) + "/deploy/cluster_certs.sh " +
                              dir_.path().string() + "/" + ca + " vsurg-control sim-a sim-b";
      ASSERT_EQ(std::system(cmd.c_str()), 0) << cmd;
    }
    options_ = As("site", "vsurg-control");
    options_.listen = "127.0.0.1:0";
    options_.health_listen = "127.0.0.1:0";
  }
  // The fixture's options with `name`'s certificate from CA `ca`, trusting the site's CA.
  ClusterOptions As(const std::string& ca, const std::string& name) const {
    ClusterOptions o = options_;
    o.tls_cert = Pki(ca, name + ".pem");
    o.tls_key = Pki(ca, name + ".key");
    o.tls_ca = Pki("site", "ca.pem");
    o.tls_refresh_s = 1;
    o.health_listen.clear();
    return o;
  }
  std::string Pki(const std::string& ca, const std::string& file) const {
    return (dir_.path() / ca / file).string();
  }
  // Replaces `to` with `from` the way a renewal does (a rename: never half a file).
  static void Renew(const std::string& from, const std::string& to) {
    std::filesystem::copy_file(from, to + ".new",
                               std::filesystem::copy_options::overwrite_existing);
    std::filesystem::rename(to + ".new", to);
  }
  // A call to a node's NodeService as `caller` (its certificate), with the site's token.
  grpc::Status CallNode(const Node& node, const ClusterOptions& caller, const std::string& name) {
    auto stub = v1::NodeService::NewStub(Channel("127.0.0.1:" + std::to_string(node.agent->port()),
                                                 WatchTlsFiles(caller).value(), name));
    auto ctx = CallContext(kToken, 10);
    v1::NodeTelemetry reply;
    return stub->Telemetry(ctx.get(), {}, &reply);
  }
  // A heartbeat for `node` to the control plane as `caller`.
  grpc::Status Beat(const ClusterOptions& caller, const std::string& node) {
    auto stub =
        v1::ClusterService::NewStub(Channel("127.0.0.1:" + std::to_string(control_->port()),
                                            WatchTlsFiles(caller).value(), "vsurg-control"));
    auto ctx = CallContext(kToken, 10);
    v1::NodeHeartbeat beat;
    beat.set_name(node);
    v1::HeartbeatReply reply;
    return stub->Heartbeat(ctx.get(), beat, &reply);
  }

  test::TempDir dir_{"cluster_tls"};
};

TEST_F(ClusterTlsTest, ANodesNameIsBoundToItsCertificate) {
  ASSERT_TRUE(options_.tls());
  // sim-a with its own certificate: registered, and the control plane reaches it (checking that
  // the address it dials serves sim-a) to create and start a session.
  Node& a = *TryAddNode("sim-a", 4, As("site", "sim-a")).value();
  WaitForNodes(1);
  auto s = control_->Create("trainee-0", "arm-torsion");
  ASSERT_TRUE(s.ok()) << s.error().message;
  ASSERT_TRUE(control_->Start(s->record.id).ok());
  EXPECT_TRUE(a.sessions->IsLive(static_cast<uint64_t>(s->record.id)));
  // A process holding sim-a's certificate and the token cannot take another name: refused at
  // start with the reason, nothing registered under it.
  auto b = TryAddNode("sim-b", 4, As("site", "sim-a"));
  ASSERT_FALSE(b.ok());
  EXPECT_EQ(b.error().code, ErrorCode::kPermissionDenied);
  EXPECT_EQ(b.error().field, "node-name");
  EXPECT_NE(b.error().message.find("names sim-a, not node sim-b"), std::string::npos)
      << b.error().message;
  // Nor beat for a name it does not carry (sim-b's certificate for sim-a's name); and the control
  // replicas' certificate names no node.
  EXPECT_EQ(Beat(As("site", "sim-b"), "sim-a").error_code(), grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(Beat(As("site", "vsurg-control"), "vsurg-control").error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  const auto nodes = control_store_->ListNodes().value();
  ASSERT_EQ(nodes.size(), 1u);
  EXPECT_EQ(nodes[0].name, "sim-a");
  EXPECT_EQ(nodes[0].epoch, 1);
  EXPECT_TRUE(a.lease.Valid());
}

TEST_F(ClusterTlsTest, OnlyTheSitesCertificatesGetInAndOnlyAControlReplicaCallsANode) {
  Node& a = *TryAddNode("sim-a", 4, As("site", "sim-a")).value();
  WaitForNodes(1);
  // A control replica's certificate calls a node; a node's own (or another node's) does not,
  // token or not.
  EXPECT_TRUE(CallNode(a, As("site", "vsurg-control"), "sim-a").ok());
  EXPECT_EQ(CallNode(a, As("site", "sim-b"), "sim-a").error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  EXPECT_EQ(CallNode(a, As("site", "sim-a"), "sim-a").error_code(),
            grpc::StatusCode::PERMISSION_DENIED);
  // A caller expecting another name at that address does not talk to it (the channel's check of
  // the server's certificate).
  EXPECT_EQ(CallNode(a, As("site", "vsurg-control"), "sim-b").error_code(),
            grpc::StatusCode::UNAVAILABLE);
  // Certificates from another CA, and plaintext, do not get past the handshake.
  EXPECT_EQ(Beat(As("other", "sim-a"), "sim-a").error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(CallNode(a, As("other", "vsurg-control"), "sim-a").error_code(),
            grpc::StatusCode::UNAVAILABLE);
  ClusterOptions plain = options_;
  plain.tls_cert = plain.tls_key = plain.tls_ca = "";
  EXPECT_EQ(Beat(plain, "sim-a").error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(CallNode(a, plain, "sim-a").error_code(), grpc::StatusCode::UNAVAILABLE);
  EXPECT_EQ(control_store_->ListNodes().value().size(), 1u);
  // The health check answers on its own plaintext port (what a probe reaches), and nothing else
  // is served there.
  ASSERT_GT(control_->health_port(), 0);
  auto health = grpc::CreateChannel("127.0.0.1:" + std::to_string(control_->health_port()),
                                    grpc::InsecureChannelCredentials());
  grpc::GenericStub stub(health);
  grpc::Slice empty_slice("", 0);
  grpc::ByteBuffer request(&empty_slice, 1), response;
  for (const char* method :
       {"/grpc.health.v1.Health/Check", "/vsurg.v1.ClusterService/Heartbeat"}) {
    grpc::ClientContext ctx;
    ctx.set_deadline(std::chrono::system_clock::now() + std::chrono::seconds(10));
    std::promise<grpc::Status> done;
    stub.UnaryCall(&ctx, method, grpc::StubOptions(), &request, &response,
                   [&](grpc::Status st) { done.set_value(st); });
    const grpc::Status st = done.get_future().get();
    if (std::string(method).find("Health") != std::string::npos) {
      ASSERT_TRUE(st.ok()) << st.error_message();
      std::vector<grpc::Slice> slices;
      ASSERT_TRUE(response.Dump(&slices).ok());
      std::string bytes;
      for (const auto& sl : slices)
        bytes.append(reinterpret_cast<const char*>(sl.begin()), sl.size());
      EXPECT_EQ(bytes, std::string("\x08\x01", 2));  // SERVING
    } else {
      EXPECT_EQ(st.error_code(), grpc::StatusCode::UNIMPLEMENTED);
    }
  }
  // Half a TLS configuration is refused at start, naming what is missing.
  ClusterOptions half = options_;
  half.tls_ca.clear();
  EXPECT_EQ(ClusterSessions::Start(*control_store_, half).error().field, "cluster-tls-ca");
  half = options_;
  half.tls_key = half.tls_cert;  // a certificate where the key should be
  EXPECT_EQ(ClusterSessions::Start(*control_store_, half).error().field, "cluster-tls-key");
}

TEST_F(ClusterTlsTest, ARenewedCertificateIsUsedWithoutARestart) {
  // A node starts with a certificate the site does not trust (a stranger's CA): it cannot get
  // in, and keeps asking.
  const ClusterOptions node = As("site", "sim-a");
  const std::string cert = dir_.path() / "sim-a.pem", key = dir_.path() / "sim-a.key";
  Renew(Pki("other", "sim-a.pem"), cert);
  Renew(Pki("other", "sim-a.key"), key);
  ClusterOptions renewing = node;
  renewing.tls_cert = cert;
  renewing.tls_key = key;
  renewing.heartbeat_timeout_s = 2;  // its start stops waiting after 3 s; its heartbeats go on
  auto a = TryAddNode("sim-a", 4, renewing);
  ASSERT_TRUE(a.ok()) << a.error().message;
  // Its heartbeat thread asks and is refused at the handshake; nothing gets in.
  const auto failed_beats = [&] {
    ops::MetricsText m;
    (*a)->agent->Collect(m);
    const std::string series = "vsurg_heartbeats_total{outcome=\"failed\"} ";
    const size_t at = m.str().find(series);
    return at == std::string::npos ? 0.0 : std::stod(m.str().substr(at + series.size()));
  };
  ASSERT_TRUE(test::Eventually(30, [&] { return failed_beats() >= 1; }));
  EXPECT_TRUE(control_store_->ListNodes().value().empty()) << "the stranger's certificate got in";
  EXPECT_FALSE((*a)->lease.held());
  // The site's certificate arrives in the same files.
  Renew(Pki("site", "sim-a.key"), key);
  Renew(Pki("site", "sim-a.pem"), cert);
  WaitForNodes(1);  // the same process, now with the renewed certificate
  EXPECT_TRUE(test::Eventually(30, [&] { return (*a)->lease.Valid(); }));
  // The control replica's own certificate renewed under it: new connections get the new one (a
  // certificate naming someone else, so a fresh caller expecting vsurg-control is refused), and
  // back.
  const std::string control_cert = options_.tls_cert, control_key = options_.tls_key;
  const std::string kept = dir_.path() / "control-kept";
  std::filesystem::copy_file(control_cert, kept + ".pem");
  std::filesystem::copy_file(control_key, kept + ".key");
  // A heartbeat from this test passes the handshake and the name check and is refused by the
  // handler (INVALID_ARGUMENT: it is no process's heartbeat); UNAVAILABLE is the handshake's
  // refusal. It passes before the renewal; right after it, either answer is possible until the
  // replica's watcher reads the files (a check there raced the watcher and failed under load).
  const auto handshake_passes = [&] {
    return Beat(node, "sim-a").error_code() == grpc::StatusCode::INVALID_ARGUMENT;
  };
  EXPECT_TRUE(handshake_passes());
  Renew(Pki("site", "sim-b.key"), control_key);
  Renew(Pki("site", "sim-b.pem"), control_cert);
  EXPECT_TRUE(test::Eventually(30, [&] {
    return Beat(node, "sim-a").error_code() == grpc::StatusCode::UNAVAILABLE;
  })) << "the control replica still presents its old certificate";
  // Back, the certificate first: for two reads the files hold a mismatched pair (a renewal caught
  // between its two renames), which must not stick. (The reads are gRPC's watcher thread on the
  // real clock, which takes no injected one; a watcher slower than this only tests less, it
  // cannot fail the test.)
  Renew(kept + ".pem", control_cert);
  std::this_thread::sleep_for(std::chrono::milliseconds(2500));
  Renew(kept + ".key", control_key);
  EXPECT_TRUE(test::Eventually(30, handshake_passes));
  EXPECT_TRUE((*a)->lease.Valid()) << "the node's own connection outlived the renewals";
}

// RFC 6125: a certificate with subject alternative names is named by them alone. One the site's
// CA signed with the SAN sim-rogue and the common name sim-a is sim-rogue, never sim-a.
TEST_F(ClusterTlsTest, ACertificateIsNamedByItsAlternativeNamesNotItsCommonName) {
  const std::string dir = Pki("site", "");
  const std::string make =
      "cd " + dir +
      " && openssl req -new -nodes -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 "
      "-keyout rogue.key -out rogue.csr -subj /CN=sim-a 2>/dev/null && "
      "printf 'subjectAltName=DNS:sim-rogue\nextendedKeyUsage=serverAuth,clientAuth\n' > "
      "rogue.ext && openssl x509 -req -in rogue.csr -CA ca.pem -CAkey ca.key -set_serial 0x5eed "
      "-days 2 -extfile rogue.ext -out rogue.pem 2>/dev/null";
  ASSERT_EQ(std::system(make.c_str()), 0) << make;
  Node& a = *TryAddNode("sim-a", 4, As("site", "sim-a")).value();
  WaitForNodes(1);
  ClusterOptions rogue = As("site", "sim-a");
  rogue.tls_cert = Pki("site", "rogue.pem");
  rogue.tls_key = Pki("site", "rogue.key");
  // It cannot beat for sim-a, nor start as a second sim-a; the real sim-a keeps its lease.
  EXPECT_EQ(Beat(rogue, "sim-a").error_code(), grpc::StatusCode::PERMISSION_DENIED);
  auto second = TryAddNode("sim-a", 4, rogue);
  ASSERT_FALSE(second.ok());
  EXPECT_EQ(second.error().code, ErrorCode::kPermissionDenied);
  EXPECT_NE(second.error().message.find("names sim-rogue, not node sim-a"), std::string::npos)
      << second.error().message;
  EXPECT_TRUE(a.lease.Valid());
  EXPECT_EQ(control_store_->ListNodes().value()[0].epoch, 1);
}

}  // namespace
}  // namespace vsurg::server::cluster
