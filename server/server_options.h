// vsurg-server's options, declared once: each default and bound comes from the settings struct
// of the component it configures (SessionManagerOptions, EndpointOptions, ClusterOptions, ...),
// and ReadServerSettings fills those structs from a parsed command line, so the program's
// --help, its parser and the components never disagree (tests/server/server_options_test.cpp).
#pragma once

#include <string>

#include "common/core/args.h"
#include "common/core/expected.h"
#include "server/cluster/cluster.h"
#include "server/control/control_plane.h"
#include "server/http/http_server.h"
#include "server/net/udp_endpoint.h"
#include "server/session/session_manager.h"

namespace vsurg::server {

// Every option of `vsurg-server [serve]`, with its help, default and bounds.
void DeclareServerOptions(cli::ArgParser& p);

// What a parsed command line asks for, as the components' own settings. Pointers between them
// (a node's lease, the metrics registry) are set by the process that runs them.
struct ServerSettings {
  std::string role = "all";  // all, control or sim
  std::string db;
  bool shared_store = false;  // db is a postgresql:// URI
  EndpointOptions endpoint;
  SessionManagerOptions sessions;
  cluster::ClusterOptions cluster;
  cluster::NodeOptions node;  // the sim role's
  ControlPlaneOptions control;
  bool http = false;  // the dashboard (on a sim node only its metrics)
  HttpServerOptions web;
  std::string ready_file;
  double drain_timeout_s = 600;
};

// The settings, or kInvalidArgument naming the option (as typed, without "--") that is wrong:
// a value outside what the components take, a role's missing requirement, an unreadable file.
Expected<ServerSettings> ReadServerSettings(const cli::ArgParser& p);

}  // namespace vsurg::server
