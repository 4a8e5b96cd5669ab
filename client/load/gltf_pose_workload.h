// --animate FILE.glb: a glTF character's own skeleton and clip played on the server. The
// skeleton and clip uploaded come from the importer (RigFromMesh, RawClipForMesh, as
// `skinserve-cli animate --on-server` uploads them); the check reads the file again with
// its own reader (skinserve/reference/gltf_reference.h) and evaluates the ORIGINAL glTF
// channels and skinning in float64, so an importer's mistake shows as a mismatch.
#pragma once

#include <memory>
#include <string>

#include "pose_workload.h"
#include "skinserve/model/status.h"

namespace skinserve::load {

// Whether `path` names a binary glTF file (.glb, any case): what the float64 check reads.
bool IsGlbPath(const std::string& path);

// The pose workload of the character in `path`: its clip `clip` (a name, or an index into
// the file's animations; empty: the first). INVALID_ARGUMENT naming the file when it is not
// a .glb, does not import, is not one skinned primitive of skin 0 without morph targets
// (what the float64 check covers: gltf_reference.h), has no such clip, or a clip without
// joint channels.
Result<std::shared_ptr<PoseWorkload>> MakeGltfPoseWorkload(const std::string& path,
                                                           const std::string& clip);

}  // namespace skinserve::load
