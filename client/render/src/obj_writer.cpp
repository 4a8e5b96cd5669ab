#include "skinserve/render/obj_writer.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "triangle_arrays.h"

namespace skinserve::render {
namespace {

Status CheckMesh(const ObjMesh& mesh) {
  if (Status s = CheckTriangleArrays(mesh.positions, mesh.normals, mesh.indices); !s.ok()) {
    return s;
  }
  for (const ObjGroup& g : mesh.groups) {
    if (g.first_index % 3 != 0 || g.index_count % 3 != 0 || g.first_index > mesh.indices.size() ||
        g.index_count > mesh.indices.size() - g.first_index) {
      return InvalidArgument(
          fmt::format("group '{}': indices [{}, +{}) are not whole triangles within the {} indices",
                      g.name, g.first_index, g.index_count, mesh.indices.size()));
    }
  }
  return Status::Ok();
}

void WriteFaces(const ObjMesh& mesh, std::size_t first, std::size_t count, uint64_t v_base,
                uint64_t vn_base, fmt::memory_buffer* out) {
  for (std::size_t i = first; i < first + count; i += 3) {
    const uint64_t a = mesh.indices[i] + 1ull, b = mesh.indices[i + 1] + 1ull,
                   c = mesh.indices[i + 2] + 1ull;
    if (mesh.normals.empty()) {
      fmt::format_to(std::back_inserter(*out), "f {} {} {}\n", v_base + a, v_base + b, v_base + c);
    } else {
      fmt::format_to(std::back_inserter(*out), "f {}//{} {}//{} {}//{}\n", v_base + a, vn_base + a,
                     v_base + b, vn_base + b, v_base + c, vn_base + c);
    }
  }
}

}  // namespace

Status WriteObj(const std::string& path, std::span<const ObjMesh> meshes) {
  uint64_t vertices = 0, triangles = 0;
  for (std::size_t m = 0; m < meshes.size(); ++m) {
    if (Status s = CheckMesh(meshes[m]); !s.ok()) {
      if (meshes.size() == 1) return s;
      return InvalidArgument(fmt::format("mesh {}: {}", m, s.message()));
    }
    vertices += meshes[m].positions.size() / 3;
    triangles += meshes[m].indices.size() / 3;
  }
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!file) return Internal(fmt::format("{}: cannot create: {}", path, std::strerror(errno)));

  // Formatted into one buffer: a frame is a few MB at most, and one write call keeps the
  // error check in one place.
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out), "# skinserve frame: {} vertices, {} triangles\n",
                 vertices, triangles);
  for (const ObjMesh& mesh : meshes) {
    const auto& p = mesh.positions;
    for (std::size_t i = 0; i < p.size(); i += 3) {
      fmt::format_to(std::back_inserter(out), "v {} {} {}\n", p[i], p[i + 1], p[i + 2]);
    }
  }
  for (const ObjMesh& mesh : meshes) {
    const auto& n = mesh.normals;
    for (std::size_t i = 0; i < n.size(); i += 3) {
      fmt::format_to(std::back_inserter(out), "vn {} {} {}\n", n[i], n[i + 1], n[i + 2]);
    }
  }
  uint64_t v_base = 0, vn_base = 0;
  for (const ObjMesh& mesh : meshes) {
    if (mesh.groups.empty()) {
      WriteFaces(mesh, 0, mesh.indices.size(), v_base, vn_base, &out);
    }
    for (const ObjGroup& g : mesh.groups) {
      fmt::format_to(std::back_inserter(out), "g {}\n", g.name);
      WriteFaces(mesh, g.first_index, g.index_count, v_base, vn_base, &out);
    }
    v_base += mesh.positions.size() / 3;
    vn_base += mesh.normals.size() / 3;
  }
  if (std::fwrite(out.data(), 1, out.size(), file.get()) != out.size()) {
    return Internal(fmt::format("{}: write failed: {}", path, std::strerror(errno)));
  }
  // fclose flushes: a full disk shows up here, not earlier.
  if (std::fclose(file.release()) != 0) {
    return Internal(fmt::format("{}: write failed: {}", path, std::strerror(errno)));
  }
  return Status::Ok();
}

Status WriteObj(const std::string& path, std::span<const float> positions,
                std::span<const float> normals, std::span<const uint32_t> indices) {
  const ObjMesh mesh{.positions = positions, .normals = normals, .indices = indices, .groups = {}};
  return WriteObj(path, std::span<const ObjMesh>(&mesh, 1));
}

std::string FrameFileName(const std::string& dir, uint64_t frame, const std::string& extension) {
  return fmt::format("{}/frame_{:04d}.{}", dir, frame, extension);
}

}  // namespace skinserve::render
