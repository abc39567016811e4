// rack-gui's backend: "subscribe", a component's stream at its full rate to the clients
// that asked (backend_impl.h, backend.h).
#include "backend_impl.h"

namespace rack::gui {

void Backend::Impl::subscribe(uint64_t client, const Request& r) {
  const uint32_t raw = r.component.raw();
  const auto [it, fresh] = streams.try_emplace(raw);
  Stream& s = it->second;
  const auto period = static_cast<int64_t>(std::llround(r.period_ms * 1e6));
  const int64_t before = s.period_ns;
  s.period_ns = fresh || s.clients.empty() ? period : std::min(s.period_ns, period);
  s.clients.insert(client);
  if (s.active && s.period_ns == before) {
    result(client, r, true, address_text(r.component) + ": streaming");
    return;
  }
  s.waiting.emplace_back(client, r);
  s.retry_at_ns = 0;
  open_stream(raw);
}

void Backend::Impl::open_stream(uint32_t raw) {
  Stream& s = streams[raw];
  if (s.pending) return;
  // A class whose samples are larger than a stream slot (a camera's 0.9 MB) is never
  // streamed: asked, it would send every sample to be dropped here (megabytes a second
  // that crowd out the polls). Known once described; maintain_streams says the same.
  if (const auto ci = class_infos.find(raw & 0xFFFF0000u);
      ci != class_infos.end() && ci->second.desc && ci->second.desc->data &&
      sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + ci->second.desc->data->size > kSlotSize) {
    s.retry_at_ns = INT64_MAX;
    s.why = address_text(Address(raw)) + ": class " + ci->second.desc->class_name + " samples of " +
            std::to_string(sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + ci->second.desc->data->size) +
            " bytes are larger than a stream slot (" + std::to_string(kSlotSize) + "): only polled";
    for (const auto& [client, req] : std::exchange(s.waiting, {})) result(client, req, false, s.why);
    return;
  }
  s.pending = true;
  if (s.mailbox == 0) {
    // Small samples to the mailbox of small slots; an undescribed class to the large.
    const auto ci = class_infos.find(raw & 0xFFFF0000u);
    const bool small = ci != class_infos.end() && ci->second.desc && ci->second.desc->data &&
                       sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + ci->second.desc->data->size <=
                           kSmallStreamSlotSize;
    s.mailbox = (small ? small_stream_mailbox : stream_mailbox).address().raw();
  }
  wire::ContDataRequest req;
  req.period_ns = s.period_ns;
  req.mailbox = s.mailbox;
  const Address a(raw);
  request(a, msg::kGetContData, req, [this, raw, a, req](const Reply* rep) {
    const auto it = streams.find(raw);
    wire::ContDataReply cd;
    const bool ok = rep != nullptr && rep->header.type == msg::kContData &&
                    wire::read_payload(rep->body, rep->native(), cd);
    if (it == streams.end()) {  // every client left meanwhile: stop it
      if (ok) {
        wire::StopContDataRequest stop;
        stop.mailbox = req.mailbox;
        request(a, msg::kStopContData, stop, [](const Reply*) {});
      }
      return;
    }
    Stream& st = it->second;
    st.pending = false;
    const int64_t now = rt::monotonic_ns();
    std::string text;
    if (ok) {
      st.active = true;
      st.why.clear();
      st.renew_at_ns = cd.lease_ns > 0 ? now + cd.lease_ns / 4 : 0;
      text = address_text(a) + ": streaming " +
             (cd.period_ns > 0 && st.period_ns > 0
                  ? "a sample every " + json(static_cast<double>(cd.period_ns) / 1e6).dump() + " ms"
                  : std::string("every sample"));
    } else {
      st.active = false;
      st.renew_at_ns = 0;
      st.retry_at_ns = now + kStreamRetryNs;
      st.why = failure(rep, "GET_CONT_DATA", a);
      text = st.why + "; still subscribed: it streams once the component is enabled";
    }
    for (const auto& [client, asked] : std::exchange(st.waiting, {})) result(client, asked, ok, text);
  });
}

void Backend::Impl::stop_stream(uint32_t raw) {
  const auto it = streams.find(raw);
  if (it == streams.end()) return;
  if (it->second.mailbox != 0) {
    wire::StopContDataRequest req;
    req.mailbox = it->second.mailbox;
    request(Address(raw), msg::kStopContData, req, [](const Reply*) {});  // best effort: it may be gone
  }
  streams.erase(it);
}

void Backend::Impl::maintain_streams() {
  const int64_t now = rt::monotonic_ns();
  for (auto& [raw, s] : streams) {
    if (s.pending) continue;
    const auto c = components.find(raw);
    const std::string state = c == components.end() ? "gone" : shown_state(c->second, now);
    if (s.active) {
      if (state != "enabled" && state != "no_reply") s.active = false;  // it went off: the ERROR may be lost
      else if (s.renew_at_ns != 0 && now >= s.renew_at_ns) open_stream(raw);
      continue;
    }
    if (state != "enabled" || now < s.retry_at_ns) continue;
    const ClassInfo* info = described(Address(raw));
    if (info == nullptr) continue;  // asked; the next round
    const std::size_t bytes = info->desc->data
                                  ? sizeof(tims::MessageHeader) + sizeof(wire::SampleHeader) + info->desc->data->size
                                  : 0;
    if (bytes == 0 || bytes > kSlotSize) {
      s.retry_at_ns = INT64_MAX;  // not streamed: no data, or a sample larger than a slot (camera images)
      s.why = address_text(Address(raw)) + ": class " + info->desc->class_name +
              (bytes == 0 ? std::string(" publishes no data")
                          : " samples of " + std::to_string(bytes) + " bytes are larger than a stream slot (" +
                                std::to_string(kSlotSize) + "): only polled");
      for (const auto& [client, req] : std::exchange(s.waiting, {})) result(client, req, false, s.why);
      continue;
    }
    open_stream(raw);
  }
}

void Backend::Impl::stream_sample(const tims::Mailbox::Received& got, std::span<const std::byte> buf) {
  const uint32_t raw = got.header.source().component().raw();
  const auto it = streams.find(raw);
  if (it == streams.end()) return;  // unsubscribed: its STOP_CONT_DATA is on the way
  Stream& s = it->second;
  const auto body = buf.subspan(sizeof(tims::MessageHeader), got.length - sizeof(tims::MessageHeader));
  if (got.header.type == msg::kError || got.header.type == msg::kEndOfStream) {
    s.active = false;
    s.renew_at_ns = 0;
    s.retry_at_ns = rt::monotonic_ns() + kStreamRetryNs;
    s.why = address_text(Address(raw)) +
            (got.header.type == msg::kError ? ": stream ended: " + error_reason(body) : ": end of stream");
    return;
  }
  if (got.header.type != msg::kData) return;
  const auto c = components.find(raw);
  if (c == components.end()) return;
  auto m = data_message(raw, c->second, got.header, body, true);
  if (!m) {
    const std::lock_guard lock(counters_mutex);
    ++counters.bad_replies;
    return;
  }
  {
    const std::lock_guard lock(counters_mutex);
    ++counters.streamed;
  }
  for (const uint64_t client : s.clients) send_to(client, *m);
}

}  // namespace rack::gui
