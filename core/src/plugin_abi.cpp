#include "rack/core/plugin_abi.h"

#include <elf.h>
#include <link.h>

#include <cstring>
#include <vector>

#include "rack/rt/input_file.h"

namespace rack::plugin_abi {

namespace {

// This machine's ELF class and byte order: a plug-in of another kind cannot be loaded.
using Ehdr = ElfW(Ehdr);
using Phdr = ElfW(Phdr);
constexpr unsigned char kOwnClass = sizeof(void*) == 8 ? ELFCLASS64 : ELFCLASS32;
constexpr unsigned char kOwnData = __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__ ? ELFDATA2LSB : ELFDATA2MSB;

std::string at(uint64_t offset) { return "byte " + std::to_string(offset) + ": "; }

template <typename T>
T load(std::span<const std::byte> head, uint64_t offset) {
  T v;
  std::memcpy(&v, head.data() + offset, sizeof v);
  return v;
}

bool printable(const char* s, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c >= 0x7f) return false;
  }
  return true;
}

// The notes of one PT_NOTE segment [offset, offset + size) of `head`: the stamp, when
// one is there. false with `why` when a note runs past the segment or a stamp is bad.
bool scan_notes(std::span<const std::byte> head, uint64_t offset, uint64_t size, uint64_t align, std::string& stamp,
                std::string& why) {
  const uint64_t end = offset + size;
  uint64_t pos = offset;
  while (end - pos >= 12) {
    const auto namesz = load<uint32_t>(head, pos);
    const auto descsz = load<uint32_t>(head, pos + 4);
    const auto type = load<uint32_t>(head, pos + 8);
    const uint64_t name_at = pos + 12;
    const uint64_t desc_at = name_at + ((uint64_t{namesz} + align - 1) & ~(align - 1));
    const uint64_t next = desc_at + ((uint64_t{descsz} + align - 1) & ~(align - 1));
    if (desc_at > end || next > end) {
      why = at(pos) + "an ELF note of " + std::to_string(namesz) + " + " + std::to_string(descsz) +
            " bytes runs past its segment (which ends at byte " + std::to_string(end) + ")";
      return false;
    }
    const bool ours = namesz == 5 && std::memcmp(head.data() + name_at, "RACK", 5) == 0 && type == kNoteType;
    if (ours) {
      if (descsz == 0 || descsz > kStampBytes) {
        why = at(pos) + "the ABI stamp note holds " + std::to_string(descsz) + " bytes (1.." +
              std::to_string(kStampBytes) + ")";
        return false;
      }
      const char* text = reinterpret_cast<const char*>(head.data() + desc_at);
      const std::size_t len = strnlen(text, descsz);
      if (len == 0 || !printable(text, len)) {
        why = at(desc_at) + "the ABI stamp is empty or not printable text";
        return false;
      }
      if (len == descsz) {  // a stamp is NUL-terminated inside its descriptor (1..63 characters)
        why = at(desc_at) + "the ABI stamp has no terminating NUL within its " + std::to_string(descsz) + " bytes";
        return false;
      }
      if (!stamp.empty() && stamp != std::string(text, len)) {
        why = at(pos) + "two different ABI stamps ('" + stamp + "', '" + std::string(text, len) + "')";
        return false;
      }
      stamp.assign(text, len);
    }
    pos = next;
  }
  return true;
}

}  // namespace

StampRead read_stamp(std::span<const std::byte> head, std::string& stamp, std::string& why) {
  stamp.clear();
  why.clear();
  if (head.size() < EI_NIDENT || std::memcmp(head.data(), ELFMAG, SELFMAG) != 0) {
    why = "not an ELF file (no \\x7fELF at byte 0)";
    return StampRead::kMalformed;
  }
  const auto ident = reinterpret_cast<const unsigned char*>(head.data());
  if (ident[EI_CLASS] != kOwnClass) {
    why = at(EI_CLASS) + std::string(ident[EI_CLASS] == ELFCLASS32 ? "a 32-bit" : "not a 64-bit") +
          " ELF object; this rackd is " + (kOwnClass == ELFCLASS64 ? "64" : "32") + "-bit";
    return StampRead::kMalformed;
  }
  if (ident[EI_DATA] != kOwnData) {
    why = at(EI_DATA) + "an ELF object of the other byte order than this machine's";
    return StampRead::kMalformed;
  }
  if (head.size() < sizeof(Ehdr)) {
    why = "the ELF header is cut short (" + std::to_string(head.size()) + " bytes)";
    return StampRead::kMalformed;
  }
  const auto eh = load<Ehdr>(head, 0);
  if (eh.e_type != ET_DYN) {
    why = at(offsetof(Ehdr, e_type)) + "not a shared object (ELF type " + std::to_string(eh.e_type) + ")";
    return StampRead::kMalformed;
  }
  if (eh.e_phnum == 0) {
    why = at(offsetof(Ehdr, e_phnum)) + "no program headers";
    return StampRead::kMalformed;
  }
  if (eh.e_phentsize != sizeof(Phdr)) {
    why = at(offsetof(Ehdr, e_phentsize)) + "program headers of " + std::to_string(eh.e_phentsize) +
          " bytes (expected " + std::to_string(sizeof(Phdr)) + ")";
    return StampRead::kMalformed;
  }
  const uint64_t ph_end = uint64_t{eh.e_phoff} + uint64_t{eh.e_phnum} * sizeof(Phdr);
  if (eh.e_phoff > head.size() || ph_end > head.size()) {
    why = at(offsetof(Ehdr, e_phoff)) + "the program headers (bytes " + std::to_string(eh.e_phoff) + ".." +
          std::to_string(ph_end) + ") lie past the " + std::to_string(head.size()) + " bytes read";
    return StampRead::kMalformed;
  }
  for (uint64_t i = 0; i < eh.e_phnum; ++i) {
    const uint64_t where = eh.e_phoff + i * sizeof(Phdr);
    const auto ph = load<Phdr>(head, where);
    if (ph.p_type != PT_NOTE) continue;
    const uint64_t off = ph.p_offset;
    const uint64_t size = ph.p_filesz;
    if (off > head.size() || size > head.size() - off) {
      why = at(where) + "a note segment (bytes " + std::to_string(off) + ", " + std::to_string(size) +
            " long) lies past the " + std::to_string(head.size()) + " bytes read";
      return StampRead::kMalformed;
    }
    // Notes are 4-aligned, those of an 8-aligned segment 8-aligned (.note.gnu.property).
    if (!scan_notes(head, off, size, ph.p_align == 8 ? uint64_t{8} : uint64_t{4}, stamp, why))
      return StampRead::kMalformed;
  }
  return stamp.empty() ? StampRead::kAbsent : StampRead::kFound;
}

std::string describe_stamp(const std::string& stamp) {
  const auto space = stamp.find(' ');
  if (space == std::string::npos) return "ABI " + stamp;
  return "ABI " + stamp.substr(0, space) + " (RACK-RT " + stamp.substr(space + 1) + ")";
}

bool check_plugin(const std::string& path, uint64_t max_bytes, std::string& error) {
  rt::InputFile file;
  if (!file.open(path, max_bytes, "plug-in", error)) return false;
  std::vector<std::byte> head(kHeadBytes);
  const long n = file.read(head.data(), head.size(), error);
  if (n < 0) return false;
  head.resize(static_cast<std::size_t>(n));
  std::string stamp, why;
  const std::string expected = rackd_stamp();
  const std::string rebuild = ": rebuild it against this RACK-RT's SDK (README, \"Plug-ins and the ABI stamp\")";
  switch (read_stamp(head, stamp, why)) {
    case StampRead::kFound:
      if (stamp == expected) return true;
      error = "plug-in " + path + " was built for plug-in " + describe_stamp(stamp) + "; this rackd expects " +
              describe_stamp(expected) + rebuild;
      return false;
    case StampRead::kAbsent:
      error = "plug-in " + path + " carries no ABI stamp (built before plug-ins were stamped, or without " +
              "rack_add_plugin); this rackd expects " + describe_stamp(expected) + rebuild;
      return false;
    case StampRead::kMalformed: break;
  }
  error = "plug-in " + path + ": not a shared object rackd can load: " + why;
  return false;
}

}  // namespace rack::plugin_abi
