// rack_client's YAML tree (internal, not installed): the first document of a host
// file as scalars, lists and maps with their line and column, from libyaml's event
// API. The tools' host-file readers (host_file.cpp, deployment.cpp) share it.
// Decodes outside input: never throws for any bytes. Not RT-safe (set-up only).
#pragma once

#include <deque>
#include <string>
#include <vector>

#include "rack/client/host_file.h"

namespace rack::yaml_tree {

// The first YAML document as a tree of scalars, lists and maps (libyaml events). An
// alias points at its anchored node (shared, not copied: no expansion blow-up).
struct Node {
  enum class Kind { kScalar, kList, kMap } kind = Kind::kScalar;
  std::string value;               // a scalar's text
  std::vector<const Node*> items;  // a list's items; a map's keys and values, alternating
  int line = 1;
  int column = 1;
  [[nodiscard]] const Node* find(const char* key) const {
    if (kind != Kind::kMap) return nullptr;
    for (std::size_t i = 0; i + 1 < items.size(); i += 2) {
      if (items[i]->kind == Kind::kScalar && items[i]->value == key) return items[i + 1];
    }
    return nullptr;
  }
};

struct Document {
  std::deque<Node> nodes;
  const Node* root = nullptr;
};

// Parses the first document of `text`; false and `error` set on a syntax error.
bool parse_document(const std::string& text, const std::string& file, Document& doc, ConfigError& error);

}  // namespace rack::yaml_tree
