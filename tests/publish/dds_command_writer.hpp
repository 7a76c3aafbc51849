// The machine application's side of the DDS commands in the tests: a writer of oegw/indicators
// in one partition, returned once it has matched the gateway's reader (discovery runs in
// Cyclone's threads, so the wait is bounded, not timed logic).
#pragma once

#include <poll.h>

#include <string>

#include "dds/dds.h"
#include "oegw.h"

namespace oegw::test {

struct DdsIndicatorWriter {
  dds_entity_t participant = 0;
  dds_entity_t writer = 0;
  // 0 < writer when it matched a reader within `max_ms`.
  DdsIndicatorWriter(dds_domainid_t domain, const std::string& partition, int max_ms = 10000) {
    participant = dds_create_participant(domain, nullptr, nullptr);
    if (participant <= 0) return;
    dds_qos_t* pq = dds_create_qos();
    dds_qset_partition1(pq, partition.c_str());
    const dds_entity_t pub = dds_create_publisher(participant, pq, nullptr);
    dds_delete_qos(pq);
    dds_qos_t* q = dds_create_qos();
    dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
    const dds_entity_t w = dds_create_writer(pub,
                                             dds_create_topic(participant, &oegw_IndicatorCommand_desc,
                                                              "oegw/indicators", nullptr, nullptr),
                                             q, nullptr);
    dds_delete_qos(q);
    if (w <= 0) return;
    dds_publication_matched_status_t ms{};
    for (int waited = 0; waited < max_ms; waited += 5) {
      if (dds_get_publication_matched_status(w, &ms) == 0 && ms.current_count > 0) {
        writer = w;
        return;
      }
      (void)::poll(nullptr, 0, 5);
    }
  }
  ~DdsIndicatorWriter() {
    if (participant > 0) dds_delete(participant);
  }
  DdsIndicatorWriter(const DdsIndicatorWriter&) = delete;
  DdsIndicatorWriter& operator=(const DdsIndicatorWriter&) = delete;
  [[nodiscard]] bool ready() const { return writer > 0; }
  [[nodiscard]] bool write(std::uint8_t instance, std::uint64_t bits) const {
    const oegw_IndicatorCommand c{instance, bits};
    return dds_write(writer, &c) == 0;
  }
};

}  // namespace oegw::test
