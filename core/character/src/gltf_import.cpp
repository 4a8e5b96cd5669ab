#include "skinserve/character/gltf_import.h"

#include <tiny_gltf.h>

#include <fmt/format.h>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <new>

#include "gltf_parts.h"

namespace skinserve {
namespace {

// Images are materials' business, not skinning's: none is decoded, so a missing or broken
// image never fails an import (tinygltf would otherwise run stb_image on every one).
bool SkipImage(tinygltf::Image*, const int, std::string*, std::string*, int, int,
               const unsigned char*, int, void*) {
  return true;
}

// Required extensions that only change materials, textures or lights leave the geometry,
// skins and animations this importer reads as the core spec states them;
// KHR_mesh_quantization's integer attributes are read (gltf_primitives.cpp). Any other
// (e.g. KHR_draco_mesh_compression, EXT_meshopt_compression) changes what the accessors mean.
bool ExtensionIsSupported(const std::string& name) {
  static const char* const kSupported[] = {
      "KHR_texture_transform", "KHR_texture_basisu",    "EXT_texture_webp", "EXT_texture_avif",
      "KHR_lights_punctual",   "KHR_mesh_quantization", "KHR_materials_"};
  for (const char* h : kSupported) {
    if (name.rfind(h, 0) == 0) return true;  // "KHR_materials_" covers the whole family
  }
  return false;
}

std::string TrimEnd(std::string s) {
  while (!s.empty() && (s.back() == '\n' || s.back() == '\r' || s.back() == ' ')) s.pop_back();
  return s;
}

Result<tinygltf::Model> Parse(std::span<const uint8_t> bytes, const std::string& base_dir) {
  const bool glb = bytes.size() >= 4 && std::memcmp(bytes.data(), "glTF", 4) == 0;
  const char* kind = glb ? "GLB" : "glTF JSON";
  if (bytes.empty()) return InvalidArgument("glTF: the input is empty");
  if (bytes.size() > std::numeric_limits<uint32_t>::max()) {
    return InvalidArgument(fmt::format("{}: {} bytes; at most {} (4 GiB) are supported", kind,
                                       bytes.size(), std::numeric_limits<uint32_t>::max()));
  }
  tinygltf::TinyGLTF loader;
  loader.SetImageLoader(SkipImage, nullptr);
  tinygltf::Model model;
  std::string err;
  std::string warn;  // only tinygltf's notes on things this importer does not use (images)
  bool loaded = false;
  const auto size = static_cast<unsigned int>(bytes.size());
  // tinygltf reports errors by its return value, but its JSON library may still throw.
  try {
    loaded =
        glb ? loader.LoadBinaryFromMemory(&model, &err, &warn, bytes.data(), size, base_dir)
            : loader.LoadASCIIFromString(
                  &model, &err, &warn, reinterpret_cast<const char*>(bytes.data()), size, base_dir);
  } catch (const std::bad_alloc&) {
    throw;  // out of memory is not the file's fault: the caller's handler reports it
  } catch (const std::exception& e) {
    loaded = false;
    err = e.what();
  }
  if (!loaded) {
    if (err.empty()) err = "tinygltf rejected it without a reason";
    return InvalidArgument(fmt::format("{} ({} bytes): {}", kind, bytes.size(), TrimEnd(err)));
  }
  for (const std::string& extension : model.extensionsRequired) {
    if (!ExtensionIsSupported(extension)) {
      return InvalidArgument(
          fmt::format("extensionsRequired: {} is not supported by this importer (supported: "
                      "KHR_mesh_quantization, KHR_texture_transform, KHR_texture_basisu, "
                      "EXT_texture_webp, EXT_texture_avif, KHR_lights_punctual, KHR_materials_*)",
                      extension));
    }
  }
  return model;
}

Result<Character> Import(const tinygltf::Model& model) {
  Character character;
  auto nodes = gltf::ImportNodes(model);
  if (!nodes.ok()) return nodes.status();
  character.nodes = std::move(nodes).value();
  auto skins = gltf::ImportSkins(model);
  if (!skins.ok()) return skins.status();
  character.skins = std::move(skins).value();
  auto primitives = gltf::ImportSkinnedPrimitives(model, character.skins);
  if (!primitives.ok()) return primitives.status();
  character.primitives = std::move(primitives).value();
  if (Status s = gltf::ImportMorphWeights(model, &character.nodes); !s.ok()) return s;
  auto clips = gltf::ImportClips(model, character.nodes);
  if (!clips.ok()) return clips.status();
  character.clips = std::move(clips).value();
  return character;
}

}  // namespace

Result<Character> LoadGltfBytes(std::span<const uint8_t> bytes, const std::string& base_dir) {
  try {
    auto model = Parse(bytes, base_dir);
    if (!model.ok()) return model.status();
    return Import(*model);
  } catch (const std::bad_alloc&) {
    return ResourceExhausted(fmt::format("glTF: out of memory importing {} bytes", bytes.size()));
  }
}

Result<Character> LoadGltfFile(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  if (!file) {
    return InvalidArgument(fmt::format("{}: cannot open: {}", path, std::strerror(errno)));
  }
  const std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(file)),
                                   std::istreambuf_iterator<char>());
  if (file.bad()) return InvalidArgument(fmt::format("{}: read failed", path));
  // External buffers of a .gltf are relative to the file's own folder.
  const std::string base_dir = std::filesystem::path(path).parent_path().string();
  auto character = LoadGltfBytes(bytes, base_dir);
  if (!character.ok()) {
    return Status(character.status().code(),
                  fmt::format("{}: {}", path, character.status().message()));
  }
  return character;
}

void PrintImportWarnings(const Character& character, const std::string& path) {
  for (const SkinnedPrimitive& p : character.primitives) {
    for (const std::string& warning : p.warnings) {
      fmt::print(stderr, "{}: warning: {}\n", path, warning);
    }
  }
}

}  // namespace skinserve
