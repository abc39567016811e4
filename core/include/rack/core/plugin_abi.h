// The plug-in ABI stamp (README "Plug-ins and the ABI stamp"). A plug-in compiles
// against RACK-RT's public headers and links no rack library: its references to
// Component, Parameter, ... bind to rackd's symbols when rackd loads it. A plug-in
// built against other headers (a Component of another layout, another entry point)
// would run with the wrong layout and crash rackd, so every plug-in carries the stamp
// of the headers it was compiled against, and rackd refuses one whose stamp is not its
// own, before dlopen() runs any of the plug-in's code.
//
// What the stamp is: "<hash> <version>", the first 16 hex digits of the SHA-256 of
// every public header of the SDK (include/rack/: rt, tims, client, core, interfaces)
// with comments and whitespace left out (cmake/RackAbiStamp.cmake, run at every build),
// and the RACK-RT version. Any other change of a public header changes the stamp: an
// out-of-tree plug-in is rebuilt against each new RACK-RT. A change of ABI that the
// headers do not show (what rackd does with a plug-in's classes) is marked by bumping
// kAbiEpoch below, which changes the hash.
//
// Where it is: an ELF note (owner "RACK", type kNoteType, the stamp text NUL-padded to
// kStampBytes) in the section .note.rack.abi, which the linker maps into a PT_NOTE
// segment (`readelf -n plugin.so` shows it). rack_add_plugin() and rack_add_class()
// compile the note into every plug-in (the generated rack_plugin_abi_note.cpp); a
// plug-in built some other way puts RACK_PLUGIN_ABI_NOTE(stamp) in one of its sources.
//
// Real-time contract: nothing here is RT-safe (set-up only: file reads, allocation).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>

namespace rack::plugin_abi {

// Bumped by hand when the plug-in ABI changes in a way no public header shows.
inline constexpr int kAbiEpoch = 1;

inline constexpr uint32_t kNoteType = 0x52414249;  // "RABI"
inline constexpr std::size_t kStampBytes = 64;     // the note's descriptor: the stamp, NUL-padded

// The note exactly as it lies in the section (ELF note layout: name and descriptor
// each padded to 4 bytes).
struct Note {
  uint32_t namesz = 0;
  uint32_t descsz = 0;
  uint32_t type = 0;
  char name[8] = {};
  char desc[kStampBytes] = {};
};
static_assert(sizeof(Note) == 12 + 8 + kStampBytes);

template <std::size_t N>
constexpr Note make_note(const char (&stamp)[N]) noexcept {
  static_assert(N >= 2 && N <= kStampBytes, "a stamp is 1..63 characters");
  Note n;
  n.namesz = 5;  // "RACK" and its NUL
  n.descsz = kStampBytes;
  n.type = kNoteType;
  n.name[0] = 'R';
  n.name[1] = 'A';
  n.name[2] = 'C';
  n.name[3] = 'K';
  for (std::size_t i = 0; i < N; ++i) n.desc[i] = stamp[i];
  return n;
}

// What read_stamp() found in the first bytes of a file.
enum class StampRead : uint8_t {
  kFound,      // `stamp` holds the plug-in's stamp
  kAbsent,     // an ELF shared object without a stamp (built before stamps, or by hand)
  kMalformed,  // not an ELF shared object of this machine's kind, or a broken one: `why`
};

// The stamp of an ELF shared object from its first bytes (`head`: from offset 0; the
// program headers and note segments must lie inside it). A plain function of a byte
// buffer (tests/fuzz/fuzz_plugin_abi.cpp): never reads outside `head`. `why` says what
// is wrong and at which byte offset.
[[nodiscard]] StampRead read_stamp(std::span<const std::byte> head, std::string& stamp, std::string& why);

// This rackd's stamp ("<hash> <version>").
[[nodiscard]] const char* rackd_stamp() noexcept;
// A stamp in words: "ABI 3f2a9c0d1e2b4a5c (RACK-RT 0.1.0)".
[[nodiscard]] std::string describe_stamp(const std::string& stamp);

// How much of a plug-in file check_plugin() reads: the ELF header, the program headers
// and the notes lie in its first page with every linker we know; a megabyte is room.
inline constexpr std::size_t kHeadBytes = std::size_t{1} << 20;

// Reads the head of the plug-in file `path` (a regular file of at most `max_bytes`)
// and compares its stamp with rackd_stamp(). false with `error` naming the file, the
// ABI it was built for and the one this rackd expects (or why it has none).
[[nodiscard]] bool check_plugin(const std::string& path, uint64_t max_bytes, std::string& error);

}  // namespace rack::plugin_abi

// Puts the stamp note into the plug-in that compiles this (once per plug-in):
//   RACK_PLUGIN_ABI_NOTE("0123456789abcdef 0.1.0");
// rack_add_plugin() does it with the stamp of the headers it compiles against.
// alignas(4): a note segment is 4-aligned (GCC would align an object this large to
// 32 bytes, which readers of notes refuse).
// clang-format off
#define RACK_PLUGIN_ABI_NOTE(stamp)                                                 \
  [[gnu::used, gnu::section(".note.rack.abi")]] alignas(4) static constexpr        \
      ::rack::plugin_abi::Note kRackPluginAbiNote = ::rack::plugin_abi::make_note(stamp)
// clang-format on
