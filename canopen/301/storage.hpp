// Store parameters (1010h) and restore default parameters (1011h), CiA 301 §7.5.2.13/14.
//
// Sub-indices (both objects): 1 = all parameters, 2 = communication parameters (1000h–1FFFh),
// 3 = application parameters (6000h–9FFFh); "all" is every index of the dictionary (including
// the manufacturer area 2000h–5FFFh, which only "all" covers). Reading any sub-index gives 1:
// "the device saves / restores parameters on command" (it never saves autonomously).
//
// Writing "save" (65766173h, bytes 73 61 76 65) to 1010h sub n writes the current values of the
// selected *writable* sub-objects (rw, wo, rwr, rww; never 1010h/1011h themselves) to the store
// file; entries of the other groups already in the file are kept. Any other value is refused
// with 08000020h; a file-system failure is reported as 06060000h (hardware error).
//
// Writing "load" (64616F6Ch) to 1011h sub n makes the defaults come back at the next reset
// (CiA 301: restored values are valid after reset node / reset communication): the stored
// values of that group are dropped from the file (the file is deleted for sub 1), atomically;
// nothing in the dictionary changes until the owner resets. Other values -> 08000020h.
//
// Durability: the file is replaced atomically — written to "<file>.tmp", fsync'd, renamed over
// "<file>", then the directory is fsync'd. Power loss at any point leaves either the previous or
// the new file; a stale "<file>.tmp" is never read.
//
// File format (text, version 1):
//     OEGW-OD-STORE 1
//     1017 00 E803                  <- index (4 hex), sub-index (2 hex), value bytes as hex
//     2000 00 -                     <- "-" = empty value (strings/DOMAIN)
//     END 2 1A2B3C4D                <- entry count, CRC-32 (IEEE 802.3) of all preceding bytes
// A file that does not parse, lacks the END line, or whose count/CRC disagree is refused as a
// whole and nothing in the dictionary changes.
//
// load(): applies the file over the current values (call after reset_to_defaults), by direct
// assignment like reset_to_defaults (no hooks, no observers: services re-read their
// configuration afterwards). Entries for objects that no longer exist, are not writable, or
// whose fixed size changed are skipped and counted.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "canopen/301/object_dictionary.hpp"
#include "canopen/can_frame.hpp"
#include "canopen/types.hpp"

namespace oegw::canopen {

// Replaces `file` with `text` so that a power loss at any moment leaves either the old or the
// new content: write a temporary file beside it, fsync, rename over `file`, fsync the directory.
// On failure returns false with `error` set and leaves `file` as it was.
bool write_file_atomically(const std::filesystem::path& file, const std::string& text, std::string& error);

class ParameterStore {
 public:
  enum class Group : std::uint8_t { All = 1, Communication = 2, Application = 3 };
  static constexpr std::uint32_t kSaveSignature = 0x65766173;  // "save", little endian
  static constexpr std::uint32_t kLoadSignature = 0x64616F6C;  // "load", little endian

  struct LoadResult {
    bool ok = false;            // false: refused (see error), nothing changed
    bool file_present = false;  // false: no stored file; defaults stay (ok = true)
    std::size_t applied = 0;
    std::size_t skipped = 0;
    std::string error;
  };

  using Key = std::pair<std::uint16_t, std::uint8_t>;
  using Entries = std::map<Key, std::vector<std::uint8_t>>;

  // Adds 1010h and 1011h (ARRAY of 3 UNSIGNED32 rw, value 1) to `od` if absent, with the hooks
  // that act on the signatures.
  ParameterStore(ObjectDictionary& od, std::filesystem::path file);
  ParameterStore(const ParameterStore&) = delete;
  ParameterStore& operator=(const ParameterStore&) = delete;

  // Applies the stored values whose index is in [first, last].
  LoadResult load(std::uint16_t first = 0x0000, std::uint16_t last = 0xFFFF);
  // What the signatures trigger; also callable by the application.
  SdoAbortCode save(Group group);
  SdoAbortCode restore_defaults(Group group);

  [[nodiscard]] const std::filesystem::path& path() const { return file_; }
  [[nodiscard]] std::filesystem::path temp_path() const;
  [[nodiscard]] const std::string& last_error() const { return last_error_; }

  // The file format, exposed for tests and tools.
  [[nodiscard]] static std::string serialize(const Entries& entries);
  // nullopt and `error` set when the text is not a complete, intact store file.
  [[nodiscard]] static std::optional<Entries> parse(const std::string& text, std::string& error);
  [[nodiscard]] static std::uint32_t crc32(const std::string& bytes);

 private:
  static std::pair<std::uint16_t, std::uint16_t> range(Group g);
  // Reads the current file: nullopt if absent; `corrupt` set if present but refused.
  std::optional<Entries> read_file(bool& corrupt, std::string& error) const;
  bool write_atomically(const std::string& text);
  bool remove_atomically();

  ObjectDictionary& od_;
  std::filesystem::path file_;
  std::string last_error_;
  Subscriptions subs_;  // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
