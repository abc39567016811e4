#include "rack/client/host_file.h"
#include "rack/tims/lcm_url.h"
#include "yaml_tree.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>
#include <yaml.h>

#include <cerrno>
#include <cstring>
#include <deque>
#include <map>

namespace rack {

std::string ConfigError::str() const {
  if (line <= 0) return file + ": " + message;
  return file + ":" + std::to_string(line) + ":" + std::to_string(column) + ": " + message;
}

std::optional<std::string> read_host_bytes(const std::string& path, std::string& error) {
  // O_NONBLOCK: opening a FIFO with no writer returns at once (then refused below).
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) {
    const int e = errno;
    error = std::string("cannot read the host file: ") + std::strerror(e);
    // A relative name from another folder (`rackd configs/demo.yaml` outside the
    // source tree) is the usual miss: say where it was looked for.
    if (e == ENOENT && !path.empty() && path.front() != '/') {
      char cwd[4096];
      if (::getcwd(cwd, sizeof cwd) != nullptr)
        error += std::string(" (looked for from the working directory ") + cwd + ")";
    }
    return std::nullopt;
  }
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (fstat(fd, &st) != 0) {
    error = std::string("cannot read the host file: ") + std::strerror(errno);
    return std::nullopt;
  }
  if (!S_ISREG(st.st_mode)) {
    error = std::string("the host file is ") +
            (S_ISFIFO(st.st_mode)                         ? "a FIFO"
             : S_ISDIR(st.st_mode)                        ? "a directory"
             : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "a device"
             : S_ISSOCK(st.st_mode)                       ? "a socket"
                                                          : "not a regular file") +
            ": a host file must be a regular file";
    return std::nullopt;
  }
  if (static_cast<uint64_t>(st.st_size) > kMaxHostFileBytes) {
    error = "the host file has " + std::to_string(st.st_size) + " bytes: at most " + std::to_string(kMaxHostFileBytes) +
            " are read";
    return std::nullopt;
  }
  // One byte more than the limit: a file that grew after fstat is refused too.
  std::string text(static_cast<std::size_t>(st.st_size) + 1, '\0');
  std::size_t have = 0;
  while (have < text.size()) {
    const ssize_t n = ::read(fd, text.data() + have, text.size() - have);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      error = std::string("cannot read the host file: ") + std::strerror(errno);
      return std::nullopt;
    }
    if (n == 0) break;
    have += static_cast<std::size_t>(n);
    if (have > kMaxHostFileBytes) {
      error = "the host file grew past " + std::to_string(kMaxHostFileBytes) + " bytes while being read";
      return std::nullopt;
    }
  }
  text.resize(have);
  return text;
}

namespace yaml_tree {

// Parses the first document of `text`; false and `error` set on a syntax error.
bool parse_document(const std::string& text, const std::string& file, Document& doc, ConfigError& error) {
  yaml_parser_t parser;
  if (yaml_parser_initialize(&parser) == 0) {
    error = {file, 0, 0, "libyaml could not start (out of memory)"};
    return false;
  }
  struct ParserCloser {
    yaml_parser_t* p;
    ~ParserCloser() { yaml_parser_delete(p); }
  } parser_closer{&parser};
  yaml_parser_set_input_string(&parser, reinterpret_cast<const unsigned char*>(text.data()), text.size());
  std::map<std::string, const Node*> anchors;
  std::vector<Node*> open;  // lists and maps being filled
  const auto fail = [&](const yaml_mark_t& m, std::string why) {
    error = {file, static_cast<int>(m.line) + 1, static_cast<int>(m.column) + 1, std::move(why)};
    return false;
  };
  for (;;) {
    yaml_event_t event;
    if (yaml_parser_parse(&parser, &event) == 0) {
      const std::string problem = parser.problem != nullptr ? parser.problem : "unreadable YAML";
      const std::string context = parser.context != nullptr ? std::string(parser.context) + ": " : "";
      return fail(parser.problem_mark, "YAML syntax: " + context + problem);
    }
    struct EventCloser {
      yaml_event_t* e;
      ~EventCloser() { yaml_event_delete(e); }
    } event_closer{&event};
    const yaml_mark_t mark = event.start_mark;
    const char* anchor = nullptr;
    Node* node = nullptr;
    switch (event.type) {
      case YAML_STREAM_END_EVENT:
      case YAML_DOCUMENT_END_EVENT: return true;  // only the first document is read (rackd refuses a second one)
      case YAML_SCALAR_EVENT:
        node = &doc.nodes.emplace_back();
        node->value.assign(reinterpret_cast<const char*>(event.data.scalar.value), event.data.scalar.length);
        anchor = reinterpret_cast<const char*>(event.data.scalar.anchor);
        break;
      case YAML_SEQUENCE_START_EVENT:
      case YAML_MAPPING_START_EVENT:
        if (open.size() >= kMaxHostNesting) {
          return fail(mark, "nested deeper than " + std::to_string(kMaxHostNesting) + " levels");
        }
        node = &doc.nodes.emplace_back();
        node->kind = event.type == YAML_SEQUENCE_START_EVENT ? Node::Kind::kList : Node::Kind::kMap;
        anchor = reinterpret_cast<const char*>(event.type == YAML_SEQUENCE_START_EVENT
                                                   ? event.data.sequence_start.anchor
                                                   : event.data.mapping_start.anchor);
        break;
      case YAML_SEQUENCE_END_EVENT:
      case YAML_MAPPING_END_EVENT:
        if (!open.empty()) open.pop_back();
        continue;
      case YAML_ALIAS_EVENT: {
        const auto it = anchors.find(reinterpret_cast<const char*>(event.data.alias.anchor));
        if (it == anchors.end()) {
          return fail(mark, std::string("the alias *") + reinterpret_cast<const char*>(event.data.alias.anchor) +
                                " names no anchor before it");
        }
        if (open.empty()) {
          doc.root = it->second;
        } else {
          open.back()->items.push_back(it->second);
        }
        continue;
      }
      default: continue;  // stream and document start, nothing
    }
    node->line = static_cast<int>(mark.line) + 1;
    node->column = static_cast<int>(mark.column) + 1;
    if (anchor != nullptr) anchors[anchor] = node;
    if (open.empty()) {
      doc.root = node;
    } else {
      open.back()->items.push_back(node);
    }
    if (node->kind != Node::Kind::kScalar) open.push_back(node);
  }
}

}  // namespace yaml_tree

using yaml_tree::Document;
using yaml_tree::Node;
using yaml_tree::parse_document;

ToolNetwork read_tool_network_text(const std::string& text, const std::string& file) {
  ToolNetwork out;
  out.url = "udpm://239.255.76.67:7667?ttl=0";
  const auto fail = [&](const Node* n, const std::string& why) {
    out.errors.push_back({file, n != nullptr ? n->line : 0, n != nullptr ? n->column : 0, why});
    return out;
  };
  Document doc;
  ConfigError syntax;
  if (!parse_document(text, file, doc, syntax)) {
    out.errors.push_back(std::move(syntax));
    return out;
  }
  const Node* root = doc.root;
  if (root == nullptr || root->kind != Node::Kind::kMap) {
    return fail(root, "a host file is a map (host, system, components, ...)");
  }
  const auto scalar = [&](const Node* map, const char* key, std::string& value) -> const Node* {
    const Node* n = map->find(key);
    if (n == nullptr) return nullptr;
    if (n->kind != Node::Kind::kScalar) {
      fail(n, std::string("'") + key + "' must be a string");
      return nullptr;
    }
    value = n->value;
    return n;
  };
  // A URL the host file gives is checked as rackd checks it (an empty or malformed one
  // is an error at its line, never a silent default).
  const auto check_url = [&](const Node* n, const char* key) {
    if (n == nullptr) return;
    const tims::LcmUrlResult parsed = tims::parse_lcm_url(out.url);
    if (!parsed.ok()) fail(n, std::string("'") + key + "': " + parsed.error);
  };
  check_url(scalar(root, "lcm_url", out.url), "lcm_url");
  if (!out.errors.empty()) return out;
  const Node* tims = root->find("tims");
  if (tims != nullptr && tims->kind == Node::Kind::kMap) {
    if (const Node* nets = tims->find("networks"); nets != nullptr) {
      if (nets->kind != Node::Kind::kList || nets->items.empty() || nets->items[0]->kind != Node::Kind::kMap) {
        return fail(nets, "'networks' must be a non-empty list of {name, url, scope, key_file}");
      }
      out.url.clear();
      const Node* url = scalar(nets->items[0], "url", out.url);
      scalar(nets->items[0], "key_file", out.key_file);
      if (out.url.empty()) return fail(nets->items[0], "the first network has no 'url'");
      check_url(url, "url");
    }
  }
  return out;
}

ToolNetwork read_tool_network(const std::string& path) {
  std::string why;
  const auto text = read_host_bytes(path, why);
  if (!text) {
    ToolNetwork out;
    out.url = "udpm://239.255.76.67:7667?ttl=0";
    out.errors.push_back({path, 0, 0, why});
    return out;
  }
  return read_tool_network_text(*text, path);
}

}  // namespace rack
