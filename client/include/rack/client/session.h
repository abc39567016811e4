// A tool's TiMS session (issue 19, item 4): the code rackctl, gdos and out-of-tree
// tools share to speak to rackd hosts without the executor. It claims a tool address
// (rack/tims/tool_address.h), joins the LCM network (with the key file when one is
// given), opens the tool's mailboxes, discovers hosts and their components, sends
// requests with retries, fans a request out to many components, and learns each
// class from its description (GET_CLASS, rack/core/class_description.h), so that a
// class the tool was not built with is named and decoded like a built-in one.
//
// Mailboxes of the tool (local mailbox numbers): 0 replies to call(); with
// `streams`, 1 data samples (the caller reads data_mailbox()) and 2 fan-out replies.
//
// Errors: the constructor throws std::runtime_error when the network cannot be
// joined or every tool address is taken; nothing else throws. What a host answers
// wrongly is a result (CallStatus, nullptr, nullopt) and, for descriptions, one line
// on stderr prefixed with the tool's name.
//
// Real-time contract: not RT-safe (tools only: allocates, blocks, prints).
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "rack/core/class_description.h"
#include "rack/tims/address.h"
#include "rack/tims/endpoint.h"
#include "rack/tims/lcm_transport.h"
#include "rack/tims/mailbox.h"
#include "rack/tims/router.h"
#include "rack/tims/tool_address.h"

namespace rack::client {

struct SessionConfig {
  std::string tool = "tool";                    // this tool's name, in warnings and the key-file check
  std::string lcm_url;                          // "": default_lcm_url()
  std::string key_file;                         // "": unauthenticated links
  int64_t timeout_ms = 2000;                    // per attempt of a request
  int64_t retries = 1;                          // attempts after the first
  int64_t discover_ms = 300;                    // how long discovery waits for hosts
  uint32_t reply_slot_bytes = 4 * 1024 * 1024;  // the largest reply (a camera frame: 0.9 MB)
  bool streams = true;                          // open the data (1) and fan-out (2) mailboxes
};

// $LCM_DEFAULT_URL when set and not empty, else rackd's default (tims::kDefaultLcmUrl).
[[nodiscard]] std::string default_lcm_url();

// `a` with its class named `class_name` (as the class describes itself): `Counter(2/0)`,
// `Counter(2/0)#3`; TiMS' spelling (Address::str()) when `class_name` is empty.
[[nodiscard]] std::string address_text(tims::Address a, const std::string& class_name);

// `Name(sys/inst)` or `Name(sys/inst)#mbx` whatever the name (a class learnt from its
// description, unknown to TiMS): the name and the address with class id 0. nullopt
// when the text is not of that shape (the name must be an identifier, the numbers 0..255).
[[nodiscard]] std::optional<std::pair<std::string, tims::Address>> parse_named_address(std::string_view text);

// The text of an ERROR body (wire::ErrorText, possibly shorter or empty).
[[nodiscard]] std::string error_reason(std::span<const std::byte> body);

class Session {
 public:
  explicit Session(SessionConfig config);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  [[nodiscard]] const SessionConfig& config() const noexcept { return config_; }
  [[nodiscard]] const std::string& url() const;
  [[nodiscard]] int64_t timeout_ns() const noexcept;
  [[nodiscard]] tims::Endpoint& endpoint() noexcept { return endpoint_; }
  // The data mailbox (local mailbox 1); only with `streams` (std::logic_error otherwise).
  [[nodiscard]] tims::Mailbox& data_mailbox();
  // The reply buffer of call(): a reply's body points into it until the next call.
  [[nodiscard]] std::span<std::byte> buffer() noexcept { return buffer_; }

  // Asks every host to announce itself (again every 100 ms: a datagram can be lost)
  // and waits up to discover_ms, less when `stop` returns true for what was heard.
  using DiscoverStop = std::function<bool(const std::vector<tims::HostInfo>&)>;
  std::vector<tims::HostInfo> discover(const DiscoverStop& stop);
  // The hosts heard so far, without asking.
  [[nodiscard]] std::vector<tims::HostInfo> hosts() const;

  // The component named `name` in its host file, by discovery.
  std::optional<tims::ComponentInfo> find_component(const std::string& name);
  // The component at system `system`, instance `instance` whose class describes
  // itself as `class_name` (its class or implementation name), by discovery and
  // GET_CLASS: addresses such as Counter(2/0) for a class TiMS does not know. The
  // description's class name is returned beside it. When no component of that class
  // runs there, the address is made from the class id of one that runs elsewhere (a
  // request to it is then answered NOT_AVAILABLE by the network).
  std::optional<std::pair<tims::ComponentInfo, std::string>> find_by_class(const std::string& class_name,
                                                                           uint8_t system, uint8_t instance);

  // The description of the class of the component at `component` (GET_CLASS, its
  // pages assembled and decoded), cached per system and class id: every component of
  // a class describes it alike. nullptr when the component does not answer it (an
  // older rackd, no such host) or its description is refused (the reason on stderr, once).
  const ClassDescription* describe(tims::Address component);
  // The descriptions of the classes of `components`, all at once: GET_CLASS to the
  // first component of each system and class not cached yet, the pages of every class
  // in parallel rounds (fan-out), within one deadline of (retries + 1) x timeout for
  // all of them, then cached as describe() caches them. Pass the components that
  // answer first: a class whose component does not answer by the deadline is cached
  // as not described (its name on stderr, once), and costs no other wait.
  void describe_all(const std::vector<tims::Address>& components);
  // The cached description of `component`'s class (describe(), describe_all()); never
  // asks. nullptr: not asked yet, or not described.
  [[nodiscard]] const ClassDescription* described(tims::Address component) const;
  // True when the last GET_CLASS to `component`'s class got no reply at all (as
  // opposed to a refusal or a malformed description): its command task does not
  // answer, so neither will the next request to it.
  [[nodiscard]] bool class_unanswered(tims::Address component) const;
  // The class name of `a`: TiMS' name, else the one its class describes (cached),
  // else Class0xNN.
  std::string class_name(tims::Address a);
  // The class name of `a` without asking: TiMS' name, else the cached description's,
  // else Class0xNN.
  [[nodiscard]] std::string known_class_name(tims::Address a) const;

  // Descriptions without waiting, for a stream that must not stall (rackctl watch):
  // describe_later() sends GET_CLASS for each class of `components` that is neither
  // cached nor being asked, and returns at once; poll_descriptions() never waits: it
  // takes the CLASS pages that arrived, asks for the next pages, and gives up on a
  // class after retries + 1 attempts of timeout each without a reply (then cached as
  // not described, with a line on stderr naming the component, as describe() does).
  // Returns how many classes are still being asked. They use the fan-out mailbox: not
  // while a fan_out() or describe_all() runs (replies of either would be dropped).
  void describe_later(const std::vector<tims::Address>& components);
  std::size_t poll_descriptions();

  // A request with --retries retries of --timeout each; the reply's body points into
  // buffer() until the next call.
  tims::CallResult call(tims::Address dest, int8_t type, std::span<const tims::ConstBuffer> body = {});

  // Sends `type` (no body) to every address of `dests` (with `streams`) and calls
  // answer(i, header) once for each that replied. What got no reply after retries + 1
  // attempts is simply not answered. At most kFanoutWindow requests are outstanding;
  // a reply to any attempt of a request counts. Returns the number of retries made.
  using Answer = std::function<void(std::size_t, const tims::MessageHeader&)>;
  uint64_t fan_out(const std::vector<tims::Address>& dests, int8_t type, const Answer& answer);
  // The same, with each reply's body (after its header; at most kFanoutSlotSize bytes).
  using AnswerWithBody = std::function<void(std::size_t, const tims::MessageHeader&, std::span<const std::byte>)>;
  uint64_t fan_out(const std::vector<tims::Address>& dests, int8_t type, const AnswerWithBody& answer);

  static constexpr uint32_t kDataSlotSize = 1024 * 1024;  // a watch stream keeps up to 16 samples
  static constexpr uint32_t kFanoutSlots = 64;            // fan-out: small replies, many at once
  // A CLASS page (kClassPageBytes and its header) fits: describe_all() fans out too.
  static constexpr uint32_t kFanoutSlotSize = 16 * 1024;
  static constexpr std::size_t kFanoutWindow = 24;
  static constexpr uint32_t kUplinkSlots = 32;

 private:
  static tims::LcmTransportConfig transport_config(const SessionConfig& c);
  // fan_out with a body per destination (`body_of(i)`, empty: none) that gives up on
  // what is still unanswered at `deadline_ns` (monotonic; INT64_MAX: none).
  using BodyOf = std::function<std::span<const tims::ConstBuffer>(std::size_t)>;
  uint64_t fan_out(const std::vector<tims::Address>& dests, int8_t type, const BodyOf& body_of,
                   const AnswerWithBody& answer, int64_t deadline_ns);
  // A description's pages assembled (or `error`): decoded, checked and cached under
  // `component`'s system and class.
  const ClassDescription* finish_description(tims::Address component, const ClassPageAssembler& pages,
                                             std::string error, bool unanswered);

  // A description being asked by describe_later(): its next page's request and the
  // sequence numbers of that page's attempts.
  struct Asking {
    tims::Address component;
    ClassPageAssembler pages;
    ClassPageRequest request;
    std::vector<uint8_t> seqs;
    uint32_t attempts = 0;  // of the current page
    int64_t deadline_ns = 0;
  };
  void ask_next_page(Asking& a);

  struct ClassEntry {
    std::optional<ClassDescription> desc;  // nullopt: not described (refused, malformed, no reply)
    bool unanswered = false;               // no reply to GET_CLASS at all
  };

  SessionConfig config_;
  // This tool's mailbox addresses, held by no other tool while it runs.
  tims::ToolAddressClaim claim_;
  tims::Router router_{tims::kToolSystem};
  tims::Mailbox reply_mailbox_;
  std::unique_ptr<tims::Mailbox> data_mailbox_;
  std::unique_ptr<tims::Mailbox> fanout_mailbox_;
  tims::Endpoint endpoint_;
  std::unique_ptr<tims::Endpoint> fanout_endpoint_;
  tims::LcmTransport transport_;
  std::vector<std::byte> buffer_;
  std::map<uint32_t, ClassEntry> classes_;  // system | class id << 16
  std::vector<Asking> asking_;              // describe_later()
};

}  // namespace rack::client
