// rack-gui's backend: the samples the dashboard draws (polled), camera images, maps
// (backend_impl.h).
#include "backend_impl.h"

namespace rack::gui {

void Backend::Impl::poll_data(uint64_t round) {
  const int64_t now = rt::monotonic_ns();
  for (auto& [raw, c] : components) {
    if (c.data_pending || shown_state(c, now) != "enabled") continue;
    const ClassInfo* info = described(Address(raw));
    if (info == nullptr || !info->desc->data) continue;
    const std::string& cls = info->desc->class_name;
    const bool fast = cls == kChassis || cls == kPosition || cls == kMcl || cls == kScan2d || cls == kPilot ||
                      cls == kLadar;
    if (cls == kCamera) {
      if (round % 5 == 0) poll_image(raw);  // once a second: 0.9 MB each
      continue;
    }
    if (!fast && round % 5 != 0) continue;
    c.data_pending = true;
    wire::GetDataRequest req;
    request(Address(raw), msg::kGetData, req, [this, raw](const Reply* r) {
      auto it = components.find(raw);
      if (it == components.end()) return;
      Component& comp = it->second;
      comp.data_pending = false;
      if (r == nullptr || r->header.type != msg::kData) return;
      if (auto m = data_message(raw, comp, r->header, r->body, false)) broadcast(std::move(*m));
    });
  }
}

std::optional<std::string> Backend::Impl::data_message(uint32_t raw, const Component& comp,
                                                       const tims::MessageHeader& header,
                                                       std::span<const std::byte> body, bool stream) {
  const auto ci = class_infos.find(raw & 0xFFFF0000u);
  if (ci == class_infos.end() || !ci->second.desc || !ci->second.desc->data) return std::nullopt;
  const ClassInfo& type = ci->second;
  const bool native = tims::body_is_native(header);
  wire::SampleHeader sh;
  if (body.size() < sizeof sh || !wire::read_payload(body.first(sizeof sh), native, sh)) return std::nullopt;
  const auto sample = body.subspan(sizeof sh);
  if (sample.size() != type.desc->data->size) return std::nullopt;
  const Address a(raw);
  const std::string& sample_class = type.desc->class_name;
  json data = json::parse(rack::payload_to_json(type.data_fields, sample, native), nullptr, false);
  if (data.is_discarded()) return std::nullopt;
  if (sample_class == kPosition) robots[comp.system].position_time_ns = sh.time_ns;
  // Whether the joystick is the chassis' active pilot (a field of its data).
  if (sample_class == kChassis && data.contains("active_pilot") && data["active_pilot"].is_number_unsigned()) {
    robots[comp.system].claimed = data["active_pilot"].get<uint64_t>() == reply_mailbox.address().raw();
  }
  trim_arrays(sample_class, data);
  // Enums and addresses by name beside the raw values (as rackctl get-data); an
  // address by the name its class describes (Pilot(0/0)).
  json names = json::object();
  const std::string names_text = rack::tools::field_names_json(
      type.desc->value_names, type.data_fields, sample, native, [this](Address named) {
        (void)described(named);  // its class name for the next sample, when not known yet
        return address_text(named);
      });
  if (!names_text.empty()) names = json::parse(names_text, nullptr, false);
  if (names.is_discarded()) names = json::object();
  json m{{"type", "data"},          {"component", address_text(a)}, {"name", comp.info.name},
         {"class", class_of(a)},    {"system", comp.system},        {"time_ns", sh.time_ns},
         {"sequence", sh.sequence}, {"data", std::move(data)},      {"names", std::move(names)}};
  if (stream) m["stream"] = true;
  return dump(m);
}

void Backend::Impl::poll_image(uint32_t raw) {
  Component& c = components[raw];
  c.data_pending = true;
  wire::GetDataRequest req;
  const tims::ConstBuffer part = tims::buffer_of(req);
  request(
      Address(raw), msg::kGetData, std::span<const tims::ConstBuffer>(&part, 1), default_timeout(),
      [this, raw](const Reply* r) {
        auto it = components.find(raw);
        if (it == components.end()) return;
        Component& comp = it->second;
        comp.data_pending = false;
        // The image's fields by name through the camera class's description
        // (CameraData: width, height, bytes used of `data`, format by its value name).
        const auto ci = class_infos.find(raw & 0xFFFF0000u);
        wire::SampleHeader sh;
        if (r == nullptr || r->header.type != msg::kData || ci == class_infos.end() || !ci->second.desc ||
            !ci->second.desc->data || r->body.size() != sizeof sh + ci->second.desc->data->size ||
            !wire::read_payload(r->body.first(sizeof sh), r->native(), sh)) {
          return;
        }
        const auto sample = r->body.subspan(sizeof sh);
        const auto& fields = ci->second.data_fields;
        const auto number = [&](const char* name) -> uint64_t {
          const tims::FieldDesc* f = rack::tools::find_field(fields, name);
          return f != nullptr ? rack::tools::unsigned_field(*f, sample, r->native()).value_or(0) : 0;
        };
        const tims::FieldDesc* pixels = rack::tools::find_field(fields, "data");
        if (pixels == nullptr || pixels->kind != tims::FieldKind::kU8 || pixels->offset > sample.size() ||
            sample.size() - pixels->offset < pixels->count) {
          return;
        }
        const std::size_t bytes = std::min<std::size_t>(number("bytes"), pixels->count);
        std::string format = "unknown";
        const auto format_value = static_cast<uint32_t>(number("format"));
        for (const auto& n : ci->second.desc->value_names) {
          const char* text = n.field == "format" ? n.name_of(format_value) : nullptr;
          if (text == nullptr) continue;
          const std::string_view v = text;
          format = v == "RGB8" ? "rgb" : v == "MONO8" ? "mono" : v == "JPEG" ? "jpeg" : "unknown";
        }
        const auto* data = reinterpret_cast<const uint8_t*>(sample.data() + pixels->offset);
        broadcast(dump(json{{"type", "image"},
                            {"component", address_text(Address(raw))},
                            {"system", comp.system},
                            {"time_ns", sh.time_ns},
                            {"width", number("width")},
                            {"height", number("height")},
                            {"frame", number("frame")},
                            {"dropped", number("dropped")},
                            {"bad_frames", number("bad_frames")},
                            {"format", format},
                            {"data", base64(std::vector<uint8_t>(data, data + bytes))}}));
      },
      image_mailbox.address());
}

void Backend::Impl::trim_arrays(const std::string& cls, json& d) {
  const auto cut = [&d](const char* count, std::initializer_list<const char*> arrays) {
    if (!d.contains(count) || !d[count].is_number_unsigned()) return;
    const auto n = d[count].get<std::size_t>();
    for (const char* a : arrays) {
      if (d.contains(a) && d[a].is_array() && d[a].size() > n)
        d[a].erase(d[a].begin() + static_cast<std::ptrdiff_t>(n), d[a].end());
    }
  };
  if (cls == kLadar) cut("beam_count", {"range", "intensity"});
  if (cls == kScan2d) cut("point_count", {"x", "y", "range", "bearing", "type"});
  if (cls == kPath) {
    cut("point_count", {"x", "y"});
    cut("waypoint_count", {"waypoint_x", "waypoint_y"});
  }
  if (cls == kMcl) cut("shown", {"particle_x", "particle_y", "particle_phi", "particle_weight"});
}

void Backend::Impl::poll_maps() {
  std::set<uint8_t> systems;
  for (const auto& [raw, c] : components) systems.insert(c.system);
  for (const uint8_t s : systems) {
    Robot& robot = robots[s];
    if (robot.map_sent || robot.map_pending) continue;
    if (robot.map_retry > 0) {
      --robot.map_retry;
      continue;
    }
    if (const auto file = configured_map(s)) {
      load_and_send_map(s, *file, "--map");
      continue;
    }
    // The map the robot localises on: MCL's, else the simulators' `map` parameter.
    std::optional<Address> holder;
    for (const char* cls : {kMcl, kLadar, kChassis}) {
      if ((holder = find(s, cls))) break;
    }
    if (!holder) {
      // The holders are found by their described class names: while a component of
      // the robot is not described yet (it has not answered), look again next round.
      bool all_described = true;
      for (const auto& [raw, c] : components) {
        if (c.system != s) continue;
        const auto ci = class_infos.find(raw & 0xFFFF0000u);
        if (tims::class_name(Address(raw).class_id()) == nullptr &&
            (ci == class_infos.end() || (!ci->second.desc && !ci->second.failed))) {
          all_described = false;
        }
      }
      if (all_described) robot.map_retry = kMapRetryRounds;
      continue;
    }
    robot.map_pending = true;
    wire::ParamName name;
    wire::copy_text(name.name, "map");
    const Address a = *holder;
    request(a, msg::kGetParam, name, [this, s, a](const Reply* r) {
      Robot& rb = robots[s];
      rb.map_pending = false;
      wire::ParamRecord p;
      if (r == nullptr || r->header.type != msg::kParam || !wire::read_payload(r->body, r->native(), p) ||
          static_cast<wire::ParamKind>(p.kind) != wire::ParamKind::kString) {
        rb.map_retry = kMapRetryRounds;  // no `map` parameter (a real robot): try the next time
        return;
      }
      const std::string file = param_text(p.string_value, sizeof p.string_value);
      if (file.empty()) {
        rb.map_retry = kMapRetryRounds;
        return;
      }
      load_and_send_map(s, file, address_text(a) + " parameter 'map'");
    });
  }
}

std::optional<std::string> Backend::Impl::configured_map(uint8_t system) const {
  std::optional<std::string> any;
  for (const auto& m : config.maps) {
    const auto eq = m.find('=');
    if (eq == std::string::npos) {
      any = m;
    } else if (m.substr(0, eq) == std::to_string(system)) {
      return m.substr(eq + 1);
    }
  }
  return any;
}

void Backend::Impl::load_and_send_map(uint8_t system, const std::string& file, const std::string& from) {
  Robot& robot = robots[system];
  std::filesystem::path path(file);
  if (path.is_relative()) path = std::filesystem::path(config.map_root) / path;
  const auto loaded = maps::load_map(path.string());
  if (!loaded.ok()) {
    robot.map_retry = kMapRetryRounds * 5;
    broadcast(
        dump(json{{"type", "notice"},
                  {"level", "error"},
                  {"text", "map of robot " + std::to_string(system) + " (" + from + "): " + loaded.error_text()}}));
    return;
  }
  const auto& m = *loaded.map;
  std::vector<uint8_t> cells(static_cast<std::size_t>(m.width()) * static_cast<std::size_t>(m.height()));
  for (int iy = 0; iy < m.height(); ++iy) {
    for (int ix = 0; ix < m.width(); ++ix) {
      cells[static_cast<std::size_t>(iy) * static_cast<std::size_t>(m.width()) +
            static_cast<std::size_t>(ix)] = static_cast<uint8_t>(m.cell_state(ix, iy));
    }
  }
  robot.map_message = dump(json{{"type", "map"},
                                {"system", system},
                                {"source", path.string()},
                                {"width", m.width()},
                                {"height", m.height()},
                                {"resolution", m.resolution()},
                                {"origin_x", m.origin_x()},
                                {"origin_y", m.origin_y()},
                                {"origin_yaw", m.origin_yaw()},
                                {"cells", base64(cells)}});
  robot.map_sent = true;
  {
    const std::lock_guard lock(greet_mutex);
    map_messages[system] = robot.map_message;
  }
  broadcast(robot.map_message);
}

}  // namespace rack::gui
