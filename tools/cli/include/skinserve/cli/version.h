// The one version string every program prints for --version: the project's version
// (CMake's project(VERSION)) and, when built from a git checkout, `git describe` at
// configure time, e.g. "0.1.0 (git dcbd29a)".
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace skinserve::cli {

const char* VersionString();

// --version on `app`, printing "<program> <VersionString()>".
void AddVersionFlag(CLI::App& app, const std::string& program);

}  // namespace skinserve::cli
