#include "upload_attack.h"

#include <grpcpp/grpcpp.h>

#include <fstream>
#include <memory>
#include <vector>

#include "skinserve/client/channel.h"
#include "skinserve/v1/skinning.grpc.pb.h"

namespace skinserve::attack {
namespace {

using namespace std::chrono_literals;

// One upload of the attack, on a connection of its own. Its thread sends the header (and,
// dripping, a chunk now and then until told to stop), then waits for the server's status:
// the server's own when it ends the upload, CANCELLED when End() comes first.
class HeldUpload {
 public:
  HeldUpload(const UploadAttackOptions& o, int index, bool drip, std::atomic<bool>* stop,
             std::atomic<uint64_t>* drip_bytes)
      : stub_(v1::Skinning::NewStub(client::MakeChannel(o.target, o.connection_base + index))) {
    writer_ = stub_->UploadMesh(&context_, &info_);
    thread_ = std::thread([this, o, drip, stop, drip_bytes] {
      v1::UploadMeshRequest header;
      header.mutable_header()->set_vertex_count(o.vertices);
      header.mutable_header()->set_influences(o.influences);
      header.mutable_header()->set_joint_count(77);
      header.mutable_header()->set_has_normals(o.normals);
      bool open = writer_->Write(header);
      // Positions of value 0: any finite floats will do, the mesh is never completed.
      v1::UploadMeshRequest chunk;
      chunk.mutable_chunk()->set_array(v1::MESH_ARRAY_POSITIONS);
      chunk.mutable_chunk()->mutable_data()->assign(o.drip_chunk_bytes / 4 * 4, '\0');
      const uint64_t values = o.drip_chunk_bytes / 4;
      for (uint64_t offset = 0;
           drip && open && offset + values <= 3ull * o.vertices && !stop->load();
           offset += values) {
        chunk.mutable_chunk()->set_offset(offset);
        open = writer_->Write(chunk);  // false: ended by the server
        if (open) drip_bytes->fetch_add(values * 4);
        for (auto until = std::chrono::steady_clock::now() + o.drip_interval;
             open && !stop->load() && std::chrono::steady_clock::now() < until;) {
          std::this_thread::sleep_for(10ms);
        }
      }
      status_ = writer_->Finish();
    });
  }

  // Cancels the upload unless the server ended it, and says how it ended.
  grpc::Status End() {
    context_.TryCancel();
    thread_.join();
    return status_;
  }

 private:
  std::unique_ptr<v1::Skinning::Stub> stub_;
  grpc::ClientContext context_;
  v1::MeshInfo info_;
  std::unique_ptr<grpc::ClientWriter<v1::UploadMeshRequest>> writer_;
  grpc::Status status_;
  std::thread thread_;
};

const char* CodeName(grpc::StatusCode code) {
  switch (code) {
    case grpc::StatusCode::OK:
      return "OK";
    case grpc::StatusCode::CANCELLED:
      return "CANCELLED (held to the end)";
    case grpc::StatusCode::RESOURCE_EXHAUSTED:
      return "RESOURCE_EXHAUSTED";
    case grpc::StatusCode::INVALID_ARGUMENT:
      return "INVALID_ARGUMENT";
    case grpc::StatusCode::UNAVAILABLE:
      return "UNAVAILABLE";
    case grpc::StatusCode::DEADLINE_EXCEEDED:
      return "DEADLINE_EXCEEDED";
    default:
      return "other";
  }
}

}  // namespace

UploadAttackRound RunUploadAttackRound(const UploadAttackOptions& o) {
  std::atomic<bool> stop{false};
  std::atomic<uint64_t> drip_bytes{0};
  std::vector<std::unique_ptr<HeldUpload>> uploads;
  for (int i = 0; i < o.header_only + o.slow_drip; ++i) {
    uploads.push_back(
        std::make_unique<HeldUpload>(o, i, /*drip=*/i >= o.header_only, &stop, &drip_bytes));
  }
  std::this_thread::sleep_for(o.hold);
  stop = true;
  // The dripping ones stop sending and wait for their status: one the server sent before
  // they are cancelled is read, not lost to the cancel.
  std::this_thread::sleep_for(200ms);
  UploadAttackRound round;
  for (auto& upload : uploads) {
    const grpc::Status status = upload->End();
    // By code and by the limit the message names ("(--max-uploads 16)"), if any.
    std::string name = CodeName(status.error_code());
    const std::string message = status.error_message();
    if (const auto flag = message.find("(--"); flag != std::string::npos) {
      const auto end = message.find_first_of(" )", flag + 1);
      name.push_back(' ');
      name.append(message, flag + 1, end == std::string::npos ? end : end - flag - 1);
    }
    ++round.endings[name];
    round.messages.emplace(name, message);
  }
  round.drip_bytes_sent = drip_bytes.load();
  return round;
}

uint64_t RssMb(pid_t pid) {
  std::ifstream status("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  uint64_t kb = 0;
  while (status >> key) {
    if (key == "VmRSS:") {
      status >> kb;
      break;
    }
  }
  return kb / 1024;
}

PeakRssSampler::PeakRssSampler(pid_t pid)
    : thread_([this, pid] {
        while (!stop_.load()) {
          const uint64_t mb = RssMb(pid);
          if (mb > peak_mb_.load()) peak_mb_.store(mb);
          std::this_thread::sleep_for(50ms);
        }
      }) {}

uint64_t PeakRssSampler::Stop() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  return peak_mb_.load();
}

}  // namespace skinserve::attack
