// --config FILE: a program's options from a TOML or INI file (CLI11's own formats), with
// one precedence for every program that takes it:
//   flag on the command line  >  config file or environment variable  >  built-in default
// The file and the environment never override each other silently: an option that both set
// to different values, and no flag sets, is a start-up error naming the variable and the
// file's line. A bad
// file (an unknown key, a value the option rejects) is a start-up error naming its line.
#pragma once

#include <CLI/CLI.hpp>

#include <optional>
#include <string>

namespace skinserve::cli {

// --config FILE on `app` (also read from `env_var` when the flag is absent; empty: none).
void AddConfigFile(CLI::App& app, const std::string& env_var);

// Parses the command line (and the config file): nullopt to go on, else the exit code
// after --help, --version or an error (printed, an error naming the file's line).
std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv);

}  // namespace skinserve::cli
