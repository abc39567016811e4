// Host files: the raw bytes (size, UTF-8, control characters) and the YAML event pass
// (duplicate keys, nesting depth, clean scalars, one document), before yaml-cpp builds
// the tree.
#include "host_loader.h"

#include <yaml-cpp/eventhandler.h>

#include <sstream>

namespace rack {

namespace {

// Length in bytes of the UTF-8 sequence at text[i] and its code point; 0 when the
// bytes there are not well-formed UTF-8 (overlong, surrogate, above U+10FFFF, cut).
std::size_t utf8_sequence(std::string_view text, std::size_t i, uint32_t& cp) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(text[i + k]); };
  const unsigned char c = b(0);
  std::size_t n = 0;
  if (c < 0x80) {
    cp = c;
    return 1;
  }
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
    cp = c & 0x1Fu;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    cp = c & 0x0Fu;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    cp = c & 0x07u;
  } else return 0;
  if (i + n > text.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((b(k) & 0xC0u) != 0x80u) return 0;
    cp = (cp << 6) | (b(k) & 0x3Fu);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF)) return 0;
  return n;
}

// A control character (C0 but tab and newline, DEL, C1) or a line/paragraph
// separator: nothing a name or value in a host file needs, all of it something that
// garbles a log line or a terminal.
bool is_control(uint32_t cp) {
  return (cp < 0x20 && cp != '\t' && cp != '\n') || (cp >= 0x7F && cp <= 0x9F) || cp == 0x2028 || cp == 0x2029;
}

std::string byte_text(unsigned char c) {
  char buf[8];
  std::snprintf(buf, sizeof buf, "0x%02x", c);
  return buf;
}

std::string code_point_text(uint32_t cp) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "U+%04X", cp);
  return buf;
}

// The first reason a string is not clean text (NUL, a control character, invalid
// UTF-8), or "" when it is.
std::string unclean_text(std::string_view text) {
  for (std::size_t i = 0; i < text.size();) {
    uint32_t cp = 0;
    const std::size_t n = utf8_sequence(text, i, cp);
    if (n == 0)
      return "invalid UTF-8 (byte " + byte_text(static_cast<unsigned char>(text[i])) + " at offset " +
             std::to_string(i) + ")";
    if (cp == 0) return "a NUL byte at offset " + std::to_string(i);
    if (is_control(cp)) return "a control character (" + code_point_text(cp) + ") at offset " + std::to_string(i);
    i += n;
  }
  return {};
}

}  // namespace

// A message as it may be printed: invalid UTF-8 and control characters (newline and
// tab too) as '?',
// at most kMaxMessage bytes.
std::string clean_host_message(const std::string& message) {
  constexpr std::size_t kMaxMessage = 1024;
  std::string out;
  for (std::size_t i = 0; i < message.size() && out.size() < kMaxMessage;) {
    uint32_t cp = 0;
    const std::size_t n = utf8_sequence(message, i, cp);
    if (n == 0 || cp < 0x20 || is_control(cp)) {  // a newline too: one message, one line
      out += '?';
      i += n == 0 ? 1 : n;
    } else {
      out.append(message, i, n);
      i += n;
    }
  }
  if (out.size() >= kMaxMessage) out += "...";
  return out;
}

namespace {

// The event pass over a host file (before it is built into nodes): yaml-cpp keeps
// every pair of a map with a repeated key and its look-up finds the first (the
// loader's iteration the last), so a repeated key is found here, from the events,
// with both places. Also: nesting depth, and every scalar (key or value, after
// escapes) is clean text of at most kMaxHostScalarBytes.
class HostFileEvents final : public YAML::EventHandler {
 public:
  HostFileEvents(const std::string& file, std::vector<ConfigError>& errors) : file_(file), errors_(errors) {}

  int documents = 0;
  YAML::Mark second_document;

  void OnDocumentStart(const YAML::Mark& mark) override {
    if (++documents == 2) second_document = mark;
  }
  void OnDocumentEnd() override {}
  void OnNull(const YAML::Mark& mark, YAML::anchor_t) override { node(mark, nullptr); }
  void OnAlias(const YAML::Mark& mark, YAML::anchor_t) override { node(mark, nullptr); }
  void OnScalar(const YAML::Mark& mark, const std::string&, YAML::anchor_t, const std::string& value) override {
    if (documents > 1) return;
    if (value.size() > kMaxHostScalarBytes) {
      error(mark, "a value of " + std::to_string(value.size()) + " bytes: at most " +
                      std::to_string(kMaxHostScalarBytes) + " bytes per key or value");
    } else if (const std::string why = unclean_text(value); !why.empty()) {
      error(mark, "this value holds " + why + ": keys and values are UTF-8 text without control characters");
    }
    node(mark, &value);
  }
  void OnSequenceStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(mark, nullptr);
    push(mark, false);
  }
  void OnSequenceEnd() override { pop(); }
  void OnMapStart(const YAML::Mark& mark, const std::string&, YAML::anchor_t, YAML::EmitterStyle::value) override {
    node(mark, nullptr);
    push(mark, true);
  }
  void OnMapEnd() override { pop(); }

 private:
  struct Frame {
    bool map = false;
    bool want_key = true;
    std::map<std::string, YAML::Mark> keys;
  };
  void error(const YAML::Mark& m, const std::string& message) {
    errors_.push_back({file_, m.line + 1, m.column + 1, message});
  }
  void node(const YAML::Mark& mark, const std::string* scalar) {
    if (documents > 1 || stack_.empty() || !stack_.back().map) return;
    Frame& f = stack_.back();
    if (f.want_key && scalar != nullptr) {
      const auto [it, fresh] = f.keys.emplace(*scalar, mark);
      if (!fresh) {
        error(mark, "duplicate key '" + *scalar + "' (first at line " + std::to_string(it->second.line + 1) +
                        "): a key may appear once in a map");
      }
    }
    f.want_key = !f.want_key;
  }
  void push(const YAML::Mark& mark, bool map) {
    if (documents > 1) return;
    if (stack_.size() == kMaxHostNesting && !deep_reported_) {
      error(mark, "nested deeper than " + std::to_string(kMaxHostNesting) + " levels");
      deep_reported_ = true;
    }
    stack_.push_back(Frame{map, true, {}});
  }
  void pop() {
    if (!stack_.empty() && documents <= 1) stack_.pop_back();
  }

  const std::string& file_;
  std::vector<ConfigError>& errors_;
  std::vector<Frame> stack_;
  bool deep_reported_ = false;
};

}  // namespace

// The raw bytes, before YAML sees them: size, NUL bytes, UTF-8, control characters
// (tab, newline and carriage return aside). False: not parsed at all.
bool HostTextCheck::check_text(std::string_view text) {
  if (text.size() > kMaxHostFileBytes) {
    report_.errors.push_back({report_.file, 0, 0,
                              "the host file has " + std::to_string(text.size()) + " bytes: at most " +
                                  std::to_string(kMaxHostFileBytes) + " are read"});
    return false;
  }
  int line = 1, column = 1;
  for (std::size_t i = 0; i < text.size();) {
    uint32_t cp = 0;
    const std::size_t n = utf8_sequence(text, i, cp);
    std::string why;
    if (n == 0) why = "invalid UTF-8 (byte " + byte_text(static_cast<unsigned char>(text[i])) + ")";
    else if (cp == 0) why = "a NUL byte";
    else if (is_control(cp) && cp != '\r') why = "a control character (" + code_point_text(cp) + ")";
    if (!why.empty()) {
      report_.errors.push_back(
          {report_.file, line, column, why + ": a host file is UTF-8 text without control characters"});
      return false;
    }
    if (cp == '\n') {
      ++line;
      column = 1;
    } else {
      ++column;
    }
    i += n;
  }
  return true;
}

// The event pass (HostFileEvents) and the rule of one document. False: the first
// document is not YAML.
bool HostTextCheck::check_events(const std::string& text) {
  std::istringstream in(text);
  YAML::Parser parser(in);
  HostFileEvents events(report_.file, report_.errors);
  try {
    parser.HandleNextDocument(events);
  } catch (const YAML::Exception& e) {
    error(e.mark, "YAML syntax: " + e.msg);
    return false;
  }
  // Whatever follows the first document (after '---' or '...') is refused, not
  // ignored: yaml-cpp's Load would read the first and drop the rest unseen.
  try {
    if (parser.HandleNextDocument(events)) {
      error(events.second_document,
            "a second YAML document: a host file is one document (remove the '---' and "
            "what follows)");
    }
  } catch (const YAML::Exception& e) {
    error(e.mark, "after the host file's document: a host file is one document (YAML syntax: " + e.msg + ")");
  }
  return true;
}

}  // namespace rack
