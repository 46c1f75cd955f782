// How the client tools reach the control plane: the shared options (--server, --token,
// --token-file, $VSURG_TOKEN, --tls-ca, --timeout), the channel, and a bearer token and a
// deadline on every call.
#pragma once

#include <memory>
#include <ostream>
#include <string>

#include "common/core/args.h"
#include "common/core/expected.h"

namespace grpc {
class Channel;
class ChannelCredentials;
class ClientContext;
class Status;
}  // namespace grpc

namespace vsurg::client {

void AddRemoteOptions(cli::ArgParser& parser);

struct Remote {
  std::shared_ptr<grpc::Channel> channel;
  std::string token;
  double timeout_s = 10;
  std::string address;                                    // host:port
  std::shared_ptr<grpc::ChannelCredentials> credentials;  // null: plaintext
  // A new channel to the same server: after the server went away, gRPC 1.51 can leave a
  // channel's subchannel failing fast with the old error long after the server is back.
  void Renew();
  // Adds the token and a deadline (timeout_s, or `timeout` seconds when > 0).
  void Prepare(grpc::ClientContext& ctx, double timeout = 0) const;
};

// A channel of its own (a local subchannel pool) that retries a lost server within a second
// (plaintext when `credentials` is null).
std::shared_ptr<grpc::Channel> MakeChannel(const std::string& address,
                                           std::shared_ptr<grpc::ChannelCredentials> credentials);

// After a successful Parse of a parser given AddRemoteOptions.
Expected<Remote> ConnectRemote(const cli::ArgParser& parser);

// "<command>: <message> (gRPC <code>)"; returns exit code 1.
int ReportRpcError(std::ostream& err, const std::string& command, const grpc::Status& status);

}  // namespace vsurg::client
