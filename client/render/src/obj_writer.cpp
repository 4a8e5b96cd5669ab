#include "skinserve/render/obj_writer.h"

#include <fmt/format.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>

#include "triangle_arrays.h"

namespace skinserve::render {

Status WriteObj(const std::string& path, std::span<const float> positions,
                std::span<const float> normals, std::span<const uint32_t> indices) {
  if (Status s = CheckTriangleArrays(positions, normals, indices); !s.ok()) return s;
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> file(std::fopen(path.c_str(), "w"), &std::fclose);
  if (!file) return Internal(fmt::format("{}: cannot create: {}", path, std::strerror(errno)));

  // Formatted into one buffer per section: a frame is a few MB at most, and one write
  // call per section keeps the error check in one place.
  fmt::memory_buffer out;
  fmt::format_to(std::back_inserter(out), "# skinserve frame: {} vertices, {} triangles\n",
                 positions.size() / 3, indices.size() / 3);
  for (std::size_t i = 0; i < positions.size(); i += 3) {
    fmt::format_to(std::back_inserter(out), "v {} {} {}\n", positions[i], positions[i + 1],
                   positions[i + 2]);
  }
  for (std::size_t i = 0; i < normals.size(); i += 3) {
    fmt::format_to(std::back_inserter(out), "vn {} {} {}\n", normals[i], normals[i + 1],
                   normals[i + 2]);
  }
  for (std::size_t i = 0; i < indices.size(); i += 3) {
    const uint64_t a = indices[i] + 1ull, b = indices[i + 1] + 1ull, c = indices[i + 2] + 1ull;
    if (normals.empty()) {
      fmt::format_to(std::back_inserter(out), "f {} {} {}\n", a, b, c);
    } else {
      fmt::format_to(std::back_inserter(out), "f {0}//{0} {1}//{1} {2}//{2}\n", a, b, c);
    }
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

std::string FrameFileName(const std::string& dir, uint64_t frame, const std::string& extension) {
  return fmt::format("{}/frame_{:04d}.{}", dir, frame, extension);
}

}  // namespace skinserve::render
