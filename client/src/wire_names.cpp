// The names of the protocol's enums (component state, data task mode, parameter
// kind, GDOS level) that tools print and parse. Declared beside their enums in
// rack/core/component.h, parameters.h and gdos.h; defined here so that the tools
// link them without the executor. All RT-safe (no allocation).
#include "rack/core/component.h"
#include "rack/core/gdos.h"
#include "rack/core/parameters.h"

namespace rack {

const char* describe(ComponentState s) noexcept {
  switch (s) {
    case ComponentState::kDisabled: return "DISABLED";
    case ComponentState::kEnabled: return "ENABLED";
    case ComponentState::kError: return "ERROR";
  }
  return "UNKNOWN";
}

const char* describe(DataTaskMode m) noexcept {
  switch (m) {
    case DataTaskMode::kNone: return "none";
    case DataTaskMode::kPeriodic: return "periodic";
    case DataTaskMode::kTriggered: return "triggered";
  }
  return "unknown";
}

const char* describe(ParamKind kind) noexcept {
  switch (kind) {
    case ParamKind::kInt: return "int";
    case ParamKind::kFloat: return "float";
    case ParamKind::kBool: return "bool";
    case ParamKind::kString: return "string";
  }
  return "unknown";
}

}  // namespace rack

namespace rack::gdos {

const char* describe(Level level) noexcept {
  switch (level) {
    case Level::kPrint: return "print";
    case Level::kError: return "error";
    case Level::kWarning: return "warning";
    case Level::kInfo: return "info";
    case Level::kDetail: return "detail";
  }
  return "unknown";
}

char letter(Level level) noexcept {
  switch (level) {
    case Level::kPrint: return 'P';
    case Level::kError: return 'E';
    case Level::kWarning: return 'W';
    case Level::kInfo: return 'I';
    case Level::kDetail: return 'D';
  }
  return '?';
}

std::optional<Level> parse_level(std::string_view t) noexcept {
  if (t == "print") return Level::kPrint;
  if (t == "error") return Level::kError;
  if (t == "warning") return Level::kWarning;
  if (t == "info") return Level::kInfo;
  if (t == "detail") return Level::kDetail;
  return std::nullopt;
}

}  // namespace rack::gdos
