// Store parameters (1010h) and restore default parameters (1011h), CiA 301 §7.5.2.13/14.
//
// Sub-indices (both objects): 1 = all parameters, 2 = communication parameters (1000h–1FFFh),
// 3 = application parameters (6000h–9FFFh); "all" is every index of the dictionary (including
// the manufacturer area 2000h–5FFFh, which only "all" covers). Reading any sub-index gives 1:
// "the device saves / restores parameters on command" (it never saves autonomously).
//
// Writing "save" (65766173h, bytes 73 61 76 65) to 1010h sub n writes the current values of the
// selected *writable* sub-objects (rw, wo, rwr, rww; never 1010h/1011h themselves, never the
// error history 1003h, which CiA 301 §7.5.2.5 makes a record of what happened, not a parameter)
// to the store file; entries of the other groups already in the file are kept (a save of one
// group merges with what is stored). Any other value is refused with 08000020h; a file-system
// failure is reported as 06060000h (hardware error).
//
// Writing "load" (64616F6Ch) to 1011h sub n makes the defaults come back at the next reset
// (CiA 301: restored values are valid after reset node / reset communication): the stored
// values of that group are dropped from the file (the file is deleted for sub 1), atomically;
// nothing in the dictionary changes until the owner resets. Other values -> 08000020h.
//
// Fails safe: a store file that is there but cannot be taken — unreadable (permissions, an I/O
// error, not a regular file), corrupt (see the format below) or a symbolic link (never followed:
// the file is replaced by rename, and a link there is somebody else's) — is "refused":
//  * load() applies nothing and says why (the owner runs on defaults and reports it: the Node
//    raises EMCY 6000h);
//  * a save or restore of one group (sub 2, 3) is refused with 06060000h and changes nothing:
//    it would keep the other groups, which cannot be read, so it would drop them. Sub 1 (all
//    groups) replaces, or deletes, the refused file: it drops nothing it does not write;
//  * a symbolic link is refused by every operation, sub 1 too (06060000h).
//
// Durability: the file is replaced atomically — written to "<file>.tmp" (created with
// O_CREAT|O_EXCL|O_NOFOLLOW, mode 0644: a link or file planted there is never written through;
// a stale one, left by a crash, is removed and the creation tried once more), fsync'd, renamed
// over "<file>", then the directory is fsync'd. Power loss at any point leaves either the
// previous or the new file; a stale "<file>.tmp" is never read.
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
// new content: write "<file>.tmp" beside it (O_CREAT|O_EXCL|O_NOFOLLOW; a stale one is removed
// first), fsync, rename over `file`, fsync the directory. On failure returns false with `error`
// set and leaves `file` as it was. A symbolic link at `file` is refused (it would be replaced by
// a plain file, silently cutting the link).
bool write_file_atomically(const std::filesystem::path& file, const std::string& text, std::string& error);

// Reads a whole file without following a symbolic link at its last component (O_NOFOLLOW).
struct PlainFile {
  enum class State : std::uint8_t { Absent, Read, Refused };
  State state = State::Absent;
  std::string text;   // Read: the content
  std::string error;  // Refused: why ("is a symbolic link", "Permission denied", ...)
};
[[nodiscard]] PlainFile read_plain_file(const std::filesystem::path& file);

class ParameterStore {
 public:
  enum class Group : std::uint8_t { All = 1, Communication = 2, Application = 3 };
  static constexpr std::uint32_t kSaveSignature = 0x65766173;  // "save", little endian
  static constexpr std::uint32_t kLoadSignature = 0x64616F6C;  // "load", little endian

  struct LoadResult {
    bool ok = false;            // false: refused (see error: unreadable, corrupt, a link), nothing changed
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
  // The file as this store last read or wrote it (absent before its first read): what the next
  // load() applies unless another program changes the file meanwhile. A run's state holds it
  // (Node::export_state), so that a gateway put in that state elsewhere (a replay) can be given
  // the store the run had; set_seen() only tells the store, the file is the caller's.
  [[nodiscard]] const PlainFile& seen() const { return seen_; }
  void set_seen(PlainFile seen) { seen_ = std::move(seen); }

  // The file format, exposed for tests and tools.
  [[nodiscard]] static std::string serialize(const Entries& entries);
  // nullopt and `error` set when the text is not a complete, intact store file.
  [[nodiscard]] static std::optional<Entries> parse(const std::string& text, std::string& error);
  [[nodiscard]] static std::uint32_t crc32(const std::string& bytes);

 private:
  static std::pair<std::uint16_t, std::uint16_t> range(Group g);
  // The file as it is now: absent, intact (entries), or refused (why).
  struct Stored {
    bool present = false;
    std::optional<Entries> entries;  // nullopt while present: refused
    std::string error;
    bool link = false;  // refused because it is a symbolic link
  };
  [[nodiscard]] Stored read_file() const;
  // A save or restore of `group` on a refused file: 0606 0000h with last_error_ set, or None.
  SdoAbortCode refuse_on(const Stored& stored, Group group, const char* what);
  bool write_atomically(const std::string& text);
  bool remove_atomically();

  ObjectDictionary& od_;
  std::filesystem::path file_;
  std::string last_error_;
  mutable PlainFile seen_;  // read_file() is const
  Subscriptions subs_;      // declared last: unregisters the OD callbacks first on destruction
};

}  // namespace oegw::canopen
