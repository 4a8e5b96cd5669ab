// The OBJ writer's files, parsed back: every vertex, normal and face as written.
#include "skinserve/render/obj_writer.h"

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>
#include <vector>

namespace skinserve::testing {
namespace {

struct ParsedObj {
  std::vector<std::string> groups;       // in file order
  std::vector<std::size_t> group_faces;  // faces under each group
  std::vector<float> positions, normals;
  std::vector<uint32_t> faces;         // 1-based, as in the file
  std::vector<uint32_t> face_normals;  // the index after "//", when present
};

ParsedObj Parse(const std::string& path) {
  ParsedObj obj;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);) {
    std::istringstream words(line);
    std::string tag;
    words >> tag;
    if (tag == "v" || tag == "vn") {
      for (int i = 0; i < 3; ++i) {
        std::string word;
        words >> word;
        (tag == "v" ? obj.positions : obj.normals).push_back(std::stof(word));
      }
    } else if (tag == "g") {
      std::string name;
      std::getline(words >> std::ws, name);
      obj.groups.push_back(name);
      obj.group_faces.push_back(0);
    } else if (tag == "f") {
      if (!obj.group_faces.empty()) ++obj.group_faces.back();
      for (std::string word; words >> word;) {
        const auto slashes = word.find("//");
        obj.faces.push_back(static_cast<uint32_t>(std::stoul(word.substr(0, slashes))));
        if (slashes != std::string::npos) {
          obj.face_normals.push_back(static_cast<uint32_t>(std::stoul(word.substr(slashes + 2))));
        }
      }
    }
  }
  return obj;
}

TEST(ObjWriterTest, PositionsNormalsAndFacesReadBackExactly) {
  // Values that need every digit of a float, and an exponent.
  const std::vector<float> positions = {0.1f, -2.5f, 3.14159274f, 1e-7f,       123456.789f, -0.0f,
                                        7.0f, 8.25f, -9.125f,     1.0f / 3.0f, 2.0f,        1e20f};
  const std::vector<float> normals = {0, 0, 1, 0, 1, 0, 1, 0, 0, 0.6f, 0.8f, 0};
  const std::vector<uint32_t> indices = {0, 1, 2, 2, 1, 3};
  const std::string path = ::testing::TempDir() + "obj-normals.obj";
  ASSERT_TRUE(render::WriteObj(path, positions, normals, indices).ok());
  const ParsedObj obj = Parse(path);
  EXPECT_EQ(obj.positions, positions);  // bit for bit: shortest round-trip formatting
  EXPECT_EQ(obj.normals, normals);
  EXPECT_EQ(obj.faces, (std::vector<uint32_t>{1, 2, 3, 3, 2, 4}));
  EXPECT_EQ(obj.face_normals, obj.faces);
}

TEST(ObjWriterTest, WithoutNormalsFacesNameOnlyVertices) {
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::vector<uint32_t> indices = {0, 1, 2};
  const std::string path = ::testing::TempDir() + "obj-plain.obj";
  ASSERT_TRUE(render::WriteObj(path, positions, {}, indices).ok());
  const ParsedObj obj = Parse(path);
  EXPECT_EQ(obj.positions.size(), 9u);
  EXPECT_TRUE(obj.normals.empty());
  EXPECT_EQ(obj.faces, (std::vector<uint32_t>{1, 2, 3}));
  EXPECT_TRUE(obj.face_normals.empty());
}

// A character's frame: two meshes (one per skin), the first with normals and two groups,
// the second without normals and one group. Faces are renumbered past the meshes before
// them; normal indices count only the meshes that have normals.
TEST(ObjWriterTest, MeshesAndGroupsOfAWholeCharacter) {
  const std::vector<float> p1 = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  const std::vector<float> n1 = {0, 0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1};
  const std::vector<uint32_t> i1 = {0, 1, 2, 1, 3, 2};
  const std::vector<float> p2 = {5, 0, 0, 6, 0, 0, 5, 1, 0};
  const std::vector<uint32_t> i2 = {0, 1, 2};
  const std::vector<render::ObjMesh> meshes = {
      {.positions = p1,
       .normals = n1,
       .indices = i1,
       .groups = {{"Body/0", 0, 3}, {"Hat/0", 3, 3}}},
      {.positions = p2, .normals = {}, .indices = i2, .groups = {{"Other/0", 0, 3}}}};
  const std::string path = ::testing::TempDir() + "obj-groups.obj";
  ASSERT_TRUE(render::WriteObj(path, meshes).ok());
  const ParsedObj obj = Parse(path);
  EXPECT_EQ(obj.groups, (std::vector<std::string>{"Body/0", "Hat/0", "Other/0"}));
  EXPECT_EQ(obj.group_faces, (std::vector<std::size_t>{1, 1, 1}));
  EXPECT_EQ(obj.positions.size(), p1.size() + p2.size());
  EXPECT_EQ(obj.normals, n1);
  EXPECT_EQ(obj.faces, (std::vector<uint32_t>{1, 2, 3, 2, 4, 3, 5, 6, 7}));
  EXPECT_EQ(obj.face_normals, (std::vector<uint32_t>{1, 2, 3, 2, 4, 3}));

  std::vector<render::ObjMesh> bad = meshes;
  bad[1].groups[0].index_count = 6;
  EXPECT_EQ(render::WriteObj(path, bad).message(),
            "mesh 1: group 'Other/0': indices [0, +6) are not whole triangles within the 3 "
            "indices");
}

TEST(ObjWriterTest, ErrorsNameTheFieldAndTheLimit) {
  const std::vector<float> positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const std::string path = ::testing::TempDir() + "obj-bad.obj";
  const std::vector<uint32_t> past_end = {0, 1, 3};
  Status s = render::WriteObj(path, positions, {}, past_end);
  EXPECT_EQ(s.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(s.message(), "indices[2] = 3 is not below vertex_count 3");

  const std::vector<uint32_t> not_triangles = {0, 1};
  EXPECT_EQ(render::WriteObj(path, positions, {}, not_triangles).message(),
            "indices: 2 is not 3 per triangle");
  const std::vector<float> short_normals = {0, 0, 1};
  const std::vector<uint32_t> triangle = {0, 1, 2};
  EXPECT_EQ(render::WriteObj(path, positions, short_normals, triangle).message(),
            "normals: 3 floats, positions have 9");

  s = render::WriteObj("/nonexistent-dir/frame.obj", positions, {}, triangle);
  EXPECT_EQ(s.code(), StatusCode::kInternal);
  EXPECT_NE(s.message().find("/nonexistent-dir/frame.obj"), std::string::npos) << s.message();
}

TEST(ObjWriterTest, FrameFileNamesSortInFrameOrder) {
  EXPECT_EQ(render::FrameFileName("out", 7, "obj"), "out/frame_0007.obj");
  EXPECT_EQ(render::FrameFileName("/tmp/x", 12345, "png"), "/tmp/x/frame_12345.png");
}

}  // namespace
}  // namespace skinserve::testing
