// A channel with a TCP connection of its own: gRPC lets channels with equal arguments share
// one connection, which would make a test's hostile and well-behaved clients one peer.
#pragma once

#include <grpcpp/grpcpp.h>

#include <memory>
#include <string>

namespace skinserve::testing {

inline std::shared_ptr<grpc::Channel> OwnConnection(const std::string& target) {
  grpc::ChannelArguments args;
  args.SetInt(GRPC_ARG_USE_LOCAL_SUBCHANNEL_POOL, 1);
  return grpc::CreateCustomChannel(target, grpc::InsecureChannelCredentials(), args);
}

}  // namespace skinserve::testing
