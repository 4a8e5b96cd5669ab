// UploadMesh from raw wire messages: the input is a sequence of length-delimited
// UploadMeshRequest messages (a varint length, then the message's bytes), as the stream
// would deliver them. Each goes through MeshAssembly (header limits, chunk order and
// bounds); a complete upload is validated and stored by the engine (weights, joint
// indices, finite values) and skinned once with an identity palette.
#include <google/protobuf/io/coded_stream.h>

#include <cstdint>
#include <cstdlib>
#include <vector>

#include "fuzz_engine.h"
#include "rpc/mesh_assembly.h"

using namespace skinserve;

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  Engine& engine = fuzz::FuzzEngine();
  server::MeshAssembly assembly(&engine);
  google::protobuf::io::CodedInputStream input(data, static_cast<int>(size));
  uint32_t length = 0;
  while (input.ReadVarint32(&length)) {
    const auto limit = input.PushLimit(static_cast<int>(length));
    v1::UploadMeshRequest message;
    if (!message.ParseFromCodedStream(&input) || !input.ConsumedEntireMessage()) return 0;
    input.PopLimit(limit);
    if (!assembly.Accept(message).ok()) return 0;  // the reactor ends the upload here
  }
  auto info = assembly.Store();
  if (!info.ok()) return 0;
  // A stored mesh is skinnable: identity palette, every output finite.
  std::vector<float> palette(12ull * info->joint_count, 0.0f);
  for (uint32_t j = 0; j < info->joint_count; ++j) {
    palette[12 * j + 0] = palette[12 * j + 5] = palette[12 * j + 10] = 1.0f;
  }
  std::vector<float> positions(3ull * info->vertex_count);
  std::vector<float> normals(info->has_normals ? 3ull * info->vertex_count : 0);
  SkinRequest request{.mesh_id = info->id,
                      .backend = "serial",
                      .palette = palette,
                      .positions = positions,
                      .normals = normals};
  if (!engine.SkinBlocking(std::move(request)).ok()) std::abort();
  engine.DeleteMesh(info->id);
  return 0;
}
