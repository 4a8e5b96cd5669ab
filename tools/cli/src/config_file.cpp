#include "skinserve/cli/config_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <string_view>
#include <vector>

namespace skinserve::cli {
namespace {

// One `key = value` line of a config file, where it is.
struct ConfigLine {
  std::string name;  // as CLI11 names it: "section.key", or "key" outside sections
  int number = 0;    // 1-based
  std::string text;  // trimmed
};

std::string Trim(std::string_view text) {
  const auto first = text.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  return std::string(text.substr(first, text.find_last_not_of(" \t\r") - first + 1));
}

// The file's key lines, read as CLI11's ConfigBase::from_config reads them (which keeps no
// line numbers): sections in brackets, ';' and '#' comments, lines under 3 characters
// ignored, a line without '=' a flag.
std::vector<ConfigLine> ReadConfigLines(const std::string& path) {
  std::vector<ConfigLine> lines;
  std::ifstream file(path);
  std::string section;
  int number = 0;
  for (std::string raw; std::getline(file, raw);) {
    ++number;
    const std::string line = Trim(raw);
    if (line.size() < 3 || line.front() == ';' || line.front() == '#') continue;
    if (line.front() == '[' && line.back() == ']') {
      section = Trim(std::string_view(line).substr(1, line.size() - 2));
      if (section.size() > 1 && section.front() == '[' && section.back() == ']') {
        section = section.substr(1, section.size() - 2);
      }
      std::string lower = section;
      std::transform(lower.begin(), lower.end(), lower.begin(),
                     [](unsigned char c) { return std::tolower(c); });
      if (lower == "default") section.clear();
      if (!section.empty()) lines.push_back({section, number, line});
      continue;
    }
    std::string key = Trim(line.substr(0, line.find('=')));
    if (key.size() >= 2 && (key.front() == '"' || key.front() == '\'') &&
        key.back() == key.front()) {
      key = key.substr(1, key.size() - 2);
    }
    lines.push_back({section.empty() ? key : section + "." + key, number, line});
  }
  return lines;
}

bool IsNameChar(char c) { return std::isalnum(static_cast<unsigned char>(c)) || c == '_'; }

// Whether `message` mentions `name` as a whole name: "threads" is in "--threads:" but
// "streams" is not in "max-streams", nor "max-streams" in "max-streams-per-connection".
bool Mentions(const std::string& message, const std::string& name) {
  for (auto at = message.find(name); at != std::string::npos; at = message.find(name, at + 1)) {
    const bool joined_left =
        at > 0 && (IsNameChar(message[at - 1]) ||
                   (message[at - 1] == '-' && at > 1 && IsNameChar(message[at - 2])));
    const auto end = at + name.size();
    const bool joined_right =
        end < message.size() && (IsNameChar(message[end]) || message[end] == '-');
    if (!joined_left && !joined_right) return true;
  }
  return false;
}

// Whether the command line itself gives `option` (then an error about it is the flag's).
bool OnCommandLine(const CLI::Option& option, int argc, char** argv) {
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    for (const std::string& name : option.get_lnames()) {
      const std::string flag = "--" + name;
      if (arg == flag || arg.starts_with(flag + "=")) return true;
    }
    for (const std::string& name : option.get_snames()) {
      if (arg.starts_with("-" + name)) return true;
    }
  }
  return false;
}

CLI::Option* OptionNamed(CLI::App& app, const std::string& name) {
  if (CLI::Option* option = app.get_option_no_throw("--" + name)) return option;
  if (name.size() == 1) return app.get_option_no_throw("-" + name);
  return nullptr;
}

std::string ConfigPath(CLI::App& app) {
  CLI::Option* config = app.get_config_ptr();
  if (config == nullptr || config->empty()) return {};
  return config->as<std::string>();
}

// The file's line an error is about: the key it names, unless the command line gives it.
const ConfigLine* LineOfError(CLI::App& app, const std::vector<ConfigLine>& lines,
                              const std::string& message, int argc, char** argv) {
  const ConfigLine* found = nullptr;
  for (const ConfigLine& line : lines) {
    if (!Mentions(message, line.name)) continue;
    const CLI::Option* option = OptionNamed(app, line.name);
    if (option != nullptr && OnCommandLine(*option, argc, argv)) continue;
    // The longest name mentioned: "a.b" over "b".
    if (found == nullptr || line.name.size() > found->name.size()) found = &line;
  }
  return found;
}

// An option the file sets to one value and its environment variable to another.
// A flag on the command line decides alone: then nothing is overridden silently.
void CheckFileAgainstEnvironment(CLI::App& app, const std::string& path,
                                 const std::vector<ConfigLine>& lines, int argc, char** argv) {
  for (const CLI::ConfigItem& item : app.get_config_formatter_base()->from_file(path)) {
    const CLI::Option* option = OptionNamed(app, item.fullname());
    if (option == nullptr || option->get_envname().empty()) continue;
    if (OnCommandLine(*option, argc, argv)) continue;
    const char* env = std::getenv(option->get_envname().c_str());
    if (env == nullptr || *env == '\0') continue;
    std::string value;
    for (const std::string& input : item.inputs) value += (value.empty() ? "" : ",") + input;
    if (value == env) continue;
    int number = 0;
    for (const ConfigLine& line : lines) {
      if (line.name == item.fullname()) number = line.number;
    }
    throw CLI::ConfigError(fmt::format(
        "{}: the config file {} line {} sets '{}' and the environment {}={}: remove one (a "
        "flag overrides both; the file and the environment must agree)",
        option->get_name(), path, number, value, option->get_envname(), env));
  }
}

}  // namespace

void AddConfigFile(CLI::App& app, const std::string& env_var) {
  CLI::Option* config =
      app.set_config("--config", "",
                     "read options from this TOML or INI file (key = value, keys as the long "
                     "flags without --); flags override it; an option it shares with an "
                     "environment variable must agree with it");
  if (!env_var.empty()) config->envname(env_var);
  // A key that is no option is an error, not ignored.
  app.allow_config_extras(CLI::config_extras_mode::error);
}

std::optional<int> ParseCommandLine(CLI::App& app, int argc, char** argv) {
  // CLI11 reads the config file before it reads the environment, so the file's variable
  // would name a file never read: it becomes --config FILE here, unless a flag gives one.
  std::vector<char*> args(argv, argv + argc);
  std::string env_file;
  if (CLI::Option* config = app.get_config_ptr(); argc > 0 && config != nullptr &&
                                                  !config->get_envname().empty() &&
                                                  !OnCommandLine(*config, argc, argv)) {
    if (const char* file = std::getenv(config->get_envname().c_str()); file && *file) {
      env_file = file;
      static char flag[] = "--config";
      args.insert(args.begin() + 1, {flag, env_file.data()});
    }
  }
  argc = static_cast<int>(args.size());
  argv = args.data();
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& error) {
    const std::string path = ConfigPath(app);
    if (error.get_exit_code() == 0 || path.empty()) return app.exit(error);
    const std::vector<ConfigLine> lines = ReadConfigLines(path);
    const ConfigLine* line = LineOfError(app, lines, error.what(), argc, argv);
    if (line == nullptr) return app.exit(error);
    return app.exit(CLI::ConfigError(fmt::format("{} (config file {} line {}: {})", error.what(),
                                                 path, line->number, line->text)));
  }
  if (const std::string path = ConfigPath(app); !path.empty()) {
    try {
      CheckFileAgainstEnvironment(app, path, ReadConfigLines(path), argc, argv);
    } catch (const CLI::ParseError& error) {
      return app.exit(error);
    }
  }
  return std::nullopt;
}

}  // namespace skinserve::cli
