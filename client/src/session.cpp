#include "rack/client/session.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <set>
#include <stdexcept>

#include "rack/rt/clock.h"
#include "rack/tims/link_auth.h"
#include "rack/tims/message.h"

namespace rack::client {

namespace msg = tims::msg;

namespace {

constexpr uint8_t kPriority = 10;

const char* reply_name(int8_t type) {
  const char* n = msg::name(type);
  return n != nullptr ? n : "unknown reply";
}

std::optional<uint8_t> small_number(std::string_view t) {
  if (t.empty() || t.size() > 3 || !std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; })) {
    return std::nullopt;
  }
  int v = 0;
  for (const char c : t) v = v * 10 + (c - '0');
  return v <= 255 ? std::optional<uint8_t>(static_cast<uint8_t>(v)) : std::nullopt;
}

// Descriptions are cached per class on each system: the address's system and class.
uint32_t class_key(tims::Address a) { return a.raw() & 0xFFFF0000u; }

// Whether `list` (Asking or describe_all's wants) already holds a component of `key`'s class.
template <typename List>
bool class_listed(const List& list, uint32_t key) {
  return std::any_of(list.begin(), list.end(), [key](const auto& w) { return class_key(w.component) == key; });
}

// The request for the next page of `pages`, with enum and address names and field units.
ClassPageRequest next_page_request(const ClassPageAssembler& pages) {
  ClassPageRequest q;
  q.offset = pages.next_offset();
  q.sections = kClassSectionValueNames | kClassSectionFieldUnits;
  return q;
}

// One reply to GET_CLASS, added to `pages`: true when the description wants another
// page; false when it is complete, or ended with `error` (a refusal or a bad page).
bool take_class_page(ClassPageAssembler& pages, const tims::MessageHeader& h, std::span<const std::byte> body,
                     std::string& error) {
  if (h.type != msg::kClass) {
    error = std::string("GET_CLASS answered ") + reply_name(h.type) +
            (h.type == msg::kError ? ": " + error_reason(body) : std::string());
    return false;
  }
  return pages.add(body, tims::body_is_native(h), error) && !pages.complete();
}

std::string no_class_reply(const SessionConfig& c) {
  return "no reply to GET_CLASS within " + std::to_string(c.timeout_ms) + " ms x " + std::to_string(c.retries + 1) +
         " attempt(s)";
}

}  // namespace

std::string default_lcm_url() {
  const char* env = std::getenv("LCM_DEFAULT_URL");
  return env != nullptr && *env != '\0' ? env : tims::kDefaultLcmUrl;
}

std::string address_text(tims::Address a, const std::string& class_name) {
  if (class_name.empty()) return a.str();
  // (appended piece by piece: `"(" + std::to_string(...)` warns falsely in GCC 12, -Wrestrict)
  std::string out = class_name;
  out += '(';
  out += std::to_string(a.system());
  out += '/';
  out += std::to_string(a.instance());
  out += ')';
  if (a.mailbox() != 0) {
    out += '#';
    out += std::to_string(a.mailbox());
  }
  return out;
}

std::optional<std::pair<std::string, tims::Address>> parse_named_address(std::string_view text) {
  const auto open = text.find('(');
  const auto slash = text.find('/', open);
  const auto close = text.find(')', slash);
  if (open == std::string_view::npos || open == 0 || slash == std::string_view::npos ||
      close == std::string_view::npos) {
    return std::nullopt;
  }
  const std::string_view name = text.substr(0, open);
  for (const char c : name) {
    if (std::isalnum(static_cast<unsigned char>(c)) == 0 && c != '_') return std::nullopt;
  }
  const auto sys = small_number(text.substr(open + 1, slash - open - 1));
  const auto inst = small_number(text.substr(slash + 1, close - slash - 1));
  uint8_t mbx = 0;
  const std::string_view tail = text.substr(close + 1);
  if (!tail.empty()) {
    const auto m = tail[0] == '#' ? small_number(tail.substr(1)) : std::nullopt;
    if (!m) return std::nullopt;
    mbx = *m;
  }
  if (!sys || !inst) return std::nullopt;
  return std::make_pair(std::string(name), tims::Address::make(*sys, 0, *inst, mbx));
}

std::string error_reason(std::span<const std::byte> body) {
  if (body.empty()) return "no reason given";
  const auto* text = reinterpret_cast<const char*>(body.data());
  std::string reason(text, strnlen(text, body.size()));
  return reason.empty() ? "no reason given" : reason;
}

tims::LcmTransportConfig Session::transport_config(const SessionConfig& c) {
  tims::LcmTransportConfig t;
  t.url = c.lcm_url.empty() ? default_lcm_url() : c.lcm_url;
  // Signs what this tool sends and verifies what it hears (rack/tims/link_auth.h).
  tims::use_key_file(t, c.tool, c.key_file);
  t.uplink_slots = kUplinkSlots;
  t.announce_period_ns = 0;  // a tool announces nothing
  t.role = tims::NodeRole::kTool;
  t.max_message_bytes = c.reply_slot_bytes;
  t.reassembly_slots = 2;
  t.large_slots = 1;
  const std::string tool = c.tool;
  t.warn = [tool](const std::string& s) { std::fprintf(stderr, "%s: %s\n", tool.c_str(), s.c_str()); };
  return t;
}

Session::Session(SessionConfig config)
    : config_(std::move(config)),
      claim_(tims::ToolAddressClaim::claim()),
      reply_mailbox_(claim_.mailbox(0), 4, config_.reply_slot_bytes),
      endpoint_(router_, reply_mailbox_, kPriority),
      transport_(router_, transport_config(config_)),
      buffer_(config_.reply_slot_bytes) {
  if (!claim_.warning().empty()) std::fprintf(stderr, "%s: %s\n", config_.tool.c_str(), claim_.warning().c_str());
  router_.add(reply_mailbox_);
  if (config_.streams) {
    data_mailbox_ = std::make_unique<tims::Mailbox>(claim_.mailbox(1), 16, kDataSlotSize);
    fanout_mailbox_ = std::make_unique<tims::Mailbox>(claim_.mailbox(2), kFanoutSlots, kFanoutSlotSize);
    fanout_endpoint_ = std::make_unique<tims::Endpoint>(router_, *fanout_mailbox_, kPriority);
    router_.add(*data_mailbox_);
    router_.add(*fanout_mailbox_);
  }
  transport_.start();
}

Session::~Session() {
  transport_.stop();
  router_.remove(reply_mailbox_.address());
  if (data_mailbox_) router_.remove(data_mailbox_->address());
  if (fanout_mailbox_) router_.remove(fanout_mailbox_->address());
}

const std::string& Session::url() const { return transport_.url(); }

int64_t Session::timeout_ns() const noexcept { return config_.timeout_ms * rt::kNsPerMs; }

tims::Mailbox& Session::data_mailbox() {
  if (!data_mailbox_) throw std::logic_error("rack::client::Session: no data mailbox without `streams`");
  return *data_mailbox_;
}

std::vector<tims::HostInfo> Session::discover(const DiscoverStop& stop) {
  const int64_t start = rt::monotonic_ns();
  const int64_t deadline = start + config_.discover_ms * rt::kNsPerMs;
  int64_t next_request = start;
  for (;;) {
    const int64_t now = rt::monotonic_ns();
    if (now >= next_request) {
      transport_.request_discovery();  // again every 100 ms: a multicast datagram can be lost
      next_request = now + 100 * rt::kNsPerMs;
    }
    auto hosts = transport_.hosts();
    if ((stop && stop(hosts)) || now >= deadline) return hosts;
    rt::sleep_for(std::min<int64_t>(10 * rt::kNsPerMs, deadline - now));
  }
}

std::vector<tims::HostInfo> Session::hosts() const { return transport_.hosts(); }

std::optional<tims::ComponentInfo> Session::find_component(const std::string& name) {
  std::optional<tims::ComponentInfo> found;
  discover([&](const std::vector<tims::HostInfo>& hosts) {
    for (const auto& h : hosts) {
      for (const auto& c : h.components) {
        if (c.name == name) {
          found = c;
          return true;
        }
      }
    }
    return false;
  });
  return found;
}

std::optional<std::pair<tims::ComponentInfo, std::string>> Session::find_by_class(const std::string& class_name,
                                                                                  uint8_t system, uint8_t instance) {
  std::optional<std::pair<tims::ComponentInfo, std::string>> found;
  discover([&](const std::vector<tims::HostInfo>& hosts) {
    // Every component at that system and instance (Chassis(0/0), Ladar(0/0), ...):
    // their classes described at once, so that one that does not answer costs one
    // shared deadline, not one timeout each.
    std::vector<tims::ComponentInfo> candidates;
    std::vector<tims::Address> addresses;
    for (const auto& h : hosts) {
      for (const auto& c : h.components) {
        if (c.address.system() != system || c.address.instance() != instance) continue;
        candidates.push_back(c);
        addresses.push_back(c.address.component());
      }
    }
    describe_all(addresses);
    for (const auto& c : candidates) {
      const ClassDescription* d = describe(c.address);
      if (d != nullptr && (d->class_name == class_name || d->impl == class_name)) {
        found = std::make_pair(c, d->class_name);
        return true;
      }
    }
    // None there: the class's id from a component of that class anywhere else (ids are
    // one per class name), so that the address is known and a request to it is
    // answered by the network (NOT_AVAILABLE) rather than by a wait here.
    std::vector<tims::Address> elsewhere;
    std::vector<tims::ComponentInfo> others;
    std::set<uint32_t> keys;
    for (const auto& h : hosts) {
      for (const auto& c : h.components) {
        if (keys.insert(class_key(c.address)).second) {
          others.push_back(c);
          elsewhere.push_back(c.address.component());
        }
      }
    }
    describe_all(elsewhere);
    for (const auto& c : others) {
      const ClassDescription* d = describe(c.address);
      if (d != nullptr && (d->class_name == class_name || d->impl == class_name)) {
        tims::ComponentInfo there;
        there.address = tims::Address::make(system, c.address.class_id(), instance);
        there.impl = c.impl;
        found = std::make_pair(there, d->class_name);
        return true;
      }
    }
    return false;
  });
  return found;
}

const ClassDescription* Session::describe(tims::Address component) {
  if (const auto it = classes_.find(class_key(component)); it != classes_.end()) {
    return it->second.desc ? &*it->second.desc : nullptr;
  }
  ClassPageAssembler pages;
  std::string error;
  bool unanswered = false;
  while (!pages.complete()) {
    const ClassPageRequest q = next_page_request(pages);
    const tims::ConstBuffer part = tims::buffer_of(q);
    const tims::CallResult r = call(component.component(), msg::kGetClass,
                                    std::span<const tims::ConstBuffer>(&part, 1));
    if (r.status != tims::CallStatus::kOk) {
      error = std::string("no reply to GET_CLASS: ") + tims::describe(r.status);
      unanswered = r.status == tims::CallStatus::kTimeout;
    } else if (take_class_page(pages, r.reply, r.body, error)) {
      continue;
    }
    break;
  }
  return finish_description(component, pages, std::move(error), unanswered);
}

void Session::describe_all(const std::vector<tims::Address>& components) {
  struct Want {
    tims::Address component;
    ClassPageAssembler pages;
    std::string error;
    bool unanswered = false;
    bool done = false;
    ClassPageRequest request;
  };
  std::vector<Want> want;
  for (const tims::Address a : components) {
    if (const uint32_t key = class_key(a); classes_.count(key) != 0 || class_listed(want, key)) continue;
    want.push_back(Want{a.component(), {}, {}, false, false, {}});
  }
  if (want.empty()) return;
  const int64_t deadline = rt::monotonic_ns() + timeout_ns() * (config_.retries + 1);
  for (;;) {
    // One round: the next page of every description still incomplete.
    std::vector<std::size_t> asked;
    std::vector<tims::Address> dests;
    for (std::size_t i = 0; i < want.size(); ++i) {
      if (want[i].done) continue;
      want[i].request = next_page_request(want[i].pages);
      asked.push_back(i);
      dests.push_back(want[i].component);
    }
    if (asked.empty()) break;
    std::vector<tims::ConstBuffer> parts;
    for (const std::size_t i : asked) parts.push_back(tims::buffer_of(want[i].request));
    std::vector<bool> answered(asked.size(), false);
    (void)fan_out(
        dests, msg::kGetClass, [&parts](std::size_t k) { return std::span<const tims::ConstBuffer>(&parts[k], 1); },
        [&](std::size_t k, const tims::MessageHeader& h, std::span<const std::byte> body) {
          answered[k] = true;
          Want& w = want[asked[k]];
          if (!take_class_page(w.pages, h, body, w.error)) w.done = true;
        },
        deadline);
    for (std::size_t k = 0; k < asked.size(); ++k) {
      if (answered[k]) continue;
      Want& w = want[asked[k]];
      w.error = no_class_reply(config_);
      w.unanswered = true;
      w.done = true;
    }
  }
  for (Want& w : want) (void)finish_description(w.component, w.pages, std::move(w.error), w.unanswered);
}

const ClassDescription* Session::finish_description(tims::Address component, const ClassPageAssembler& pages,
                                                    std::string error, bool unanswered) {
  ClassEntry& slot = classes_[class_key(component)];
  slot.unanswered = unanswered;
  ClassDescription d;
  if (error.empty() && !decode_class_description(pages.bytes(), d, error)) error = "class description: " + error;
  if (!error.empty()) {
    std::fprintf(stderr, "%s: %s: %s\n", config_.tool.c_str(), component.component().str().c_str(), error.c_str());
    return nullptr;
  }
  if (d.class_id != component.class_id()) {
    std::fprintf(stderr, "%s: %s: describes class id 0x%02x, not its own\n", config_.tool.c_str(),
                 component.component().str().c_str(), d.class_id);
    return nullptr;
  }
  slot.desc = std::move(d);
  return &*slot.desc;
}

std::string Session::known_class_name(tims::Address a) const {
  if (const char* cls = tims::class_name(a.class_id())) return cls;
  if (const ClassDescription* d = described(a)) return d->class_name;
  char text[16];
  std::snprintf(text, sizeof text, "Class0x%02x", a.class_id());
  return text;
}

void Session::ask_next_page(Asking& a) {
  a.request = next_page_request(a.pages);
  const tims::ConstBuffer part = tims::buffer_of(a.request);
  uint8_t seq = 0;
  // Not even queued counts as an attempt too: its deadline passes like any other.
  (void)fanout_endpoint_->send(a.component, msg::kGetClass, std::span<const tims::ConstBuffer>(&part, 1),
                               tims::Address(), &seq);
  a.seqs.push_back(seq);
  ++a.attempts;
  a.deadline_ns = rt::monotonic_ns() + timeout_ns();
}

void Session::describe_later(const std::vector<tims::Address>& components) {
  if (!fanout_mailbox_) throw std::logic_error("rack::client::Session: no fan-out mailbox without `streams`");
  for (const tims::Address a : components) {
    if (const uint32_t key = class_key(a); classes_.count(key) != 0 || class_listed(asking_, key)) continue;
    asking_.push_back(Asking{a.component(), {}, {}, {}, 0, 0});
    ask_next_page(asking_.back());
  }
}

std::size_t Session::poll_descriptions() {
  if (asking_.empty()) return 0;
  std::vector<std::byte> buf(kFanoutSlotSize);
  std::vector<std::pair<std::size_t, std::string>> ended;  // index, error ("" = complete)
  for (;;) {
    const auto got = fanout_mailbox_->receive(buf, tims::Mailbox::kNonBlocking);
    if (got.status != tims::RecvStatus::kOk) break;
    for (std::size_t i = 0; i < asking_.size(); ++i) {
      Asking& a = asking_[i];
      if (got.header.source() != a.component ||
          std::find(a.seqs.begin(), a.seqs.end(), got.header.seq) == a.seqs.end() ||
          std::any_of(ended.begin(), ended.end(), [i](const auto& e) { return e.first == i; })) {
        continue;
      }
      const std::size_t have = std::min(got.length, buf.size());
      const std::size_t skip = std::min(have, sizeof(tims::MessageHeader));
      const std::span<const std::byte> body(buf.data() + skip, have - skip);
      std::string error;
      if (take_class_page(a.pages, got.header, body, error)) {
        a.seqs.clear();
        a.attempts = 0;
        ask_next_page(a);
        break;
      }
      ended.emplace_back(i, std::move(error));
      break;
    }
    // Anything else: a duplicate (a reply to an earlier attempt) or stray: dropped.
  }
  const int64_t now = rt::monotonic_ns();
  for (std::size_t i = 0; i < asking_.size(); ++i) {
    Asking& a = asking_[i];
    if (now < a.deadline_ns || std::any_of(ended.begin(), ended.end(), [i](const auto& e) { return e.first == i; })) {
      continue;
    }
    if (a.attempts < static_cast<uint32_t>(config_.retries + 1)) {
      ask_next_page(a);
      continue;
    }
    ended.emplace_back(i, no_class_reply(config_));
  }
  // Finished ones leave the list (from the back, so the indices stay valid).
  std::sort(ended.begin(), ended.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
  for (auto& [i, error] : ended) {
    const bool unanswered = error.rfind("no reply", 0) == 0;
    (void)finish_description(asking_[i].component, asking_[i].pages, std::move(error), unanswered);
    asking_.erase(asking_.begin() + static_cast<std::ptrdiff_t>(i));
  }
  return asking_.size();
}

const ClassDescription* Session::described(tims::Address component) const {
  const auto it = classes_.find(class_key(component));
  return it != classes_.end() && it->second.desc ? &*it->second.desc : nullptr;
}

bool Session::class_unanswered(tims::Address component) const {
  const auto it = classes_.find(class_key(component));
  return it != classes_.end() && it->second.unanswered;
}

std::string Session::class_name(tims::Address a) {
  if (const char* cls = tims::class_name(a.class_id())) return cls;
  if (const ClassDescription* d = describe(a)) return d->class_name;
  char text[16];
  std::snprintf(text, sizeof text, "Class0x%02x", a.class_id());
  return text;
}

tims::CallResult Session::call(tims::Address dest, int8_t type, std::span<const tims::ConstBuffer> body) {
  return endpoint_.call_with_retry(dest, type, body, buffer_,
                                   {timeout_ns(), static_cast<uint32_t>(config_.retries + 1)});
}

uint64_t Session::fan_out(const std::vector<tims::Address>& dests, int8_t type, const Answer& answer) {
  return fan_out(dests, type,
                 AnswerWithBody([&answer](std::size_t i, const tims::MessageHeader& h, std::span<const std::byte>) {
                   answer(i, h);
                 }));
}

uint64_t Session::fan_out(const std::vector<tims::Address>& dests, int8_t type, const AnswerWithBody& answer) {
  return fan_out(
      dests, type, [](std::size_t) { return std::span<const tims::ConstBuffer>(); }, answer, INT64_MAX);
}

uint64_t Session::fan_out(const std::vector<tims::Address>& dests, int8_t type, const BodyOf& body_of,
                          const AnswerWithBody& answer, int64_t deadline_ns) {
  if (!fanout_mailbox_) throw std::logic_error("rack::client::Session: no fan-out mailbox without `streams`");
  struct Pending {
    std::vector<uint8_t> seqs;  // of every attempt so far
    int64_t deadline = 0;
    bool in_flight = false;
    bool done = false;
  };
  std::vector<Pending> p(dests.size());
  const auto attempts = static_cast<std::size_t>(config_.retries + 1);
  uint64_t retries = 0;
  std::size_t in_flight = 0;
  std::vector<std::byte> buf(kFanoutSlotSize);
  for (;;) {
    int64_t now = rt::monotonic_ns();
    if (now >= deadline_ns) return retries;  // what is still unanswered stays so
    int64_t earliest = deadline_ns;
    bool waiting = false;
    for (std::size_t i = 0; i < p.size(); ++i) {
      auto& r = p[i];
      if (r.done) continue;
      if (r.in_flight && now >= r.deadline) {  // this attempt timed out
        r.in_flight = false;
        --in_flight;
        if (r.seqs.size() >= attempts) {
          r.done = true;
          continue;
        }
      }
      if (!r.in_flight && in_flight < kFanoutWindow) {
        // Back-pressure: the uplink drops its oldest message when full.
        (void)transport_.wait_uplink(kUplinkSlots / 2, timeout_ns());
        uint8_t seq = 0;
        const auto st = fanout_endpoint_->send(dests[i], type, body_of(i), tims::Address(), &seq);
        if (!r.seqs.empty()) ++retries;
        r.seqs.push_back(seq);
        now = rt::monotonic_ns();
        r.deadline = now + timeout_ns();
        if (!tims::delivered(st)) {  // not even queued: counts as an attempt
          if (r.seqs.size() >= attempts) r.done = true;
          continue;
        }
        r.in_flight = true;
        ++in_flight;
      }
      if (r.in_flight) earliest = std::min(earliest, r.deadline);
      waiting = true;
    }
    if (!waiting) return retries;
    if (in_flight == 0) continue;  // everything left waits for a window slot: none busy
    const int64_t left = std::max<int64_t>(earliest - now, 0);
    const auto got = fanout_mailbox_->receive(buf, left);
    if (got.status != tims::RecvStatus::kOk) continue;
    for (std::size_t i = 0; i < p.size(); ++i) {
      auto& r = p[i];
      if (r.done || got.header.source() != dests[i] ||
          std::find(r.seqs.begin(), r.seqs.end(), got.header.seq) == r.seqs.end()) {
        continue;
      }
      if (r.in_flight) --in_flight;
      r.in_flight = false;
      r.done = true;
      const std::size_t have = std::min(got.length, buf.size());
      const std::size_t skip = std::min(have, sizeof(tims::MessageHeader));
      answer(i, got.header, std::span<const std::byte>(buf.data() + skip, have - skip));
      break;
    }
    // Anything else is a duplicate (a reply to a retried request that was answered
    // already) or a stray message: dropped.
  }
}

}  // namespace rack::client
