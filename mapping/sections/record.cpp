// The `record` section: the black box of `oegw run` (docs/guides/black-box.md; every key in
// docs/reference/mapping-file.md#record-the-black-box-optional-off-unless-enabled). Only the form
// is checked here; whether the folder can be made is a fact of the machine, which `oegw check` asks
// (mapping/deployment.cpp).
#include "mapping/sections/sections.hpp"

namespace oegw::mapping::sections {

void read_record(YamlReader& r, const MapEntry& sec, RecordConfig& c) {
  c.where = r.loc(sec.key);
  const auto es = r.entries(sec.value, "record", {"enabled", "dir", "max_mib", "span_s", "segments", "queue_kib"},
                            "a map with enabled, dir, max_mib, span_s, segments, queue_kib");
  if (const auto* e = r.find(es, "enabled"))
    if (auto b = r.boolean(*e, "record enabled")) c.enabled = *b;
  if (const auto* e = r.find(es, "dir"))
    if (auto d = r.string(*e, "record dir")) {
      if (d->back() == '/' && d->size() > 1) d->pop_back();
      c.dir = r.path(*d);
      c.dir_where = r.loc(e->value);
    }
  // A ring of at least 1 MiB and 10 s (a segment must hold more than its header), at most 1 TiB
  // and a week; 2..1000 segments; a queue of 64 KiB .. 256 MiB.
  r.set_int(es, "max_mib", "record max_mib", 1, 1 << 20, c.max_mib);
  r.set_int(es, "span_s", "record span_s", 10, 7 * 24 * 3600, c.span_s);
  r.set_int(es, "segments", "record segments", 2, 1000, c.segments);
  r.set_int(es, "queue_kib", "record queue_kib", 64, 256 * 1024, c.queue_kib);
}

}  // namespace oegw::mapping::sections
