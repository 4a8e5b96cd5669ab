// LostUploadOf: what a frame's NOT_FOUND names, read from the server's own messages
// (docs/serving/animation.md#errors; a tick's character's prefixed "character N: ").
#include "skinserve/client/lost_upload.h"

#include <gtest/gtest.h>

namespace skinserve::client {
namespace {

using Kind = LostUpload::Kind;

TEST(LostUploadTest, NamesTheMeshTheSkeletonOrTheClip) {
  EXPECT_EQ(LostUploadOf(NotFound("mesh 'm1' is not stored on this server; upload it again"), "m1"),
            (LostUpload{Kind::kMesh, "m1"}));
  EXPECT_EQ(LostUploadOf(NotFound("pose.skeleton_id 's9' is not stored: upload the skeleton "
                                  "(UploadSkeleton)"),
                         "m1"),
            (LostUpload{Kind::kSkeleton, "s9"}));
  EXPECT_EQ(LostUploadOf(NotFound("character 4: pose.layers[2].clip_id 'c7' is not stored: "
                                  "upload the clip (UploadClip)"),
                         "m1"),
            (LostUpload{Kind::kClip, "c7"}));
  // Anything else, or a field without its quoted id, is the mesh's.
  EXPECT_EQ(LostUploadOf(NotFound("pose.layers[0].clip_id is odd"), "m2"),
            (LostUpload{Kind::kMesh, "m2"}));
  EXPECT_EQ(LostUploadOf(NotFound(""), "m3"), (LostUpload{Kind::kMesh, "m3"}));
}

}  // namespace
}  // namespace skinserve::client
