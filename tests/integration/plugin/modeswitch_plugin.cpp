// A component class in a plug-in (a shared library named under `plugins:` in a host
// file), for the mode-switch test: its report must symbolize to this file's line
// through the plug-in's own load address and build id.
#include <fcntl.h>
#include <unistd.h>

#include <memory>

#include "rack/core/component.h"
#include "rack/core/registry.h"

namespace {

class PluginDemo final : public rack::Component {
 protected:
  void init() override { fd_ = ::open("/dev/null", O_WRONLY | O_CLOEXEC); }
  void cleanup() override {
    if (fd_ >= 0) ::close(fd_);
  }
  rack::CommandResult command(const rack::tims::MessageHeader& request, std::span<const std::byte>) override {
    if (request.type != 21) return rack::CommandResult::kUnknown;
    write_something();
    reply(request, rack::tims::msg::kOk);
    return rack::CommandResult::kHandled;
  }

 private:
  __attribute__((noinline)) void write_something() {
    written_ += ::write(fd_, "plug-in\n", 8);  // PLUGIN-LINE: SYSCALL
  }
  int fd_ = -1;
  long written_ = 0;
};

}  // namespace

extern "C" void rack_register_components(rack::ComponentRegistry& registry) {
  registry.add({"PluginDemo", 0x90, "test: a plug-in class that makes a system call in a command",
                [] { return std::make_unique<PluginDemo>(); }});
}
