// The COB-ID rules of CiA 301 §7.3.5 (Table 36, the predefined connection set and the
// restricted CAN-IDs) in canopen/types.hpp: what a PDO may use and what a node occupies.
#include <gtest/gtest.h>

#include "canopen/types.hpp"

namespace oegw::canopen {
namespace {

TEST(CobId, RestrictedCanIdsAreThoseOfTable36) {
  for (std::uint32_t id : {0x000u, 0x001u, 0x07Fu, 0x101u, 0x180u, 0x581u, 0x5FFu, 0x601u, 0x67Fu, 0x6E0u, 0x6FFu,
                           0x701u, 0x77Fu, 0x780u, 0x7E4u, 0x7E5u, 0x7FFu})
    EXPECT_TRUE(cob::restricted(id)) << std::hex << id;
  // SYNC and TIME, the PDO and EMCY ranges, the free 680h..6DFh are not restricted.
  for (std::uint32_t id :
       {0x080u, 0x081u, 0x0FFu, 0x100u, 0x181u, 0x1FFu, 0x200u, 0x57Fu, 0x580u, 0x600u, 0x680u, 0x6DFu, 0x700u})
    EXPECT_FALSE(cob::restricted(id)) << std::hex << id;
}

TEST(CobId, PredefinedConnectionSetOfANode) {
  const auto set = cob::predefined_connection_set(NodeId{0x11});
  const std::pair<std::string_view, std::uint32_t> expected[] = {{"EMCY", 0x091},
                                                                 {"TPDO1", 0x191},
                                                                 {"RPDO1", 0x211},
                                                                 {"TPDO2", 0x291},
                                                                 {"RPDO2", 0x311},
                                                                 {"TPDO3", 0x391},
                                                                 {"RPDO3", 0x411},
                                                                 {"TPDO4", 0x491},
                                                                 {"RPDO4", 0x511},
                                                                 {"SDO server->client", 0x591},
                                                                 {"SDO client->server", 0x611},
                                                                 {"heartbeat", 0x711}};
  ASSERT_EQ(set.size(), std::size(expected));
  for (std::size_t i = 0; i < set.size(); ++i) {
    EXPECT_EQ(set[i].service, expected[i].first) << i;
    EXPECT_EQ(set[i].cob_id, expected[i].second) << set[i].service;
    // No default COB-ID of a node-ID 1..127 is restricted, except the SDO and heartbeat ones.
    EXPECT_EQ(cob::restricted(set[i].cob_id), set[i].index == 0) << set[i].service;
  }
  // The entries that re-assign them.
  EXPECT_EQ(set[0].index, 0x1014);
  EXPECT_EQ(set[0].sub, 0);
  EXPECT_EQ(set[1].index, 0x1800);
  EXPECT_EQ(set[2].index, 0x1400);
  EXPECT_EQ(set[7].index, 0x1803);
  EXPECT_EQ(set[8].index, 0x1403);
  for (const auto& d : set) {
    if (d.index != 0) {
      EXPECT_TRUE(cob::is_pdo_or_emcy_cob_entry(d.index, d.sub)) << d.service;
    }
  }
}

TEST(CobId, EntriesHoldingAPdoOrEmcyCobId) {
  EXPECT_TRUE(cob::is_pdo_or_emcy_cob_entry(0x1400, 1));
  EXPECT_TRUE(cob::is_pdo_or_emcy_cob_entry(0x15FF, 1));
  EXPECT_TRUE(cob::is_pdo_or_emcy_cob_entry(0x1800, 1));
  EXPECT_TRUE(cob::is_pdo_or_emcy_cob_entry(0x19FF, 1));
  EXPECT_TRUE(cob::is_pdo_or_emcy_cob_entry(0x1014, 0));
  EXPECT_FALSE(cob::is_pdo_or_emcy_cob_entry(0x1800, 2));  // transmission type
  EXPECT_FALSE(cob::is_pdo_or_emcy_cob_entry(0x1A00, 1));  // a mapping entry
  EXPECT_FALSE(cob::is_pdo_or_emcy_cob_entry(0x1600, 1));
  EXPECT_FALSE(cob::is_pdo_or_emcy_cob_entry(0x1014, 1));
  EXPECT_FALSE(cob::is_pdo_or_emcy_cob_entry(0x1200, 1));  // SDO server: not a PDO/EMCY
  EXPECT_FALSE(cob::is_pdo_or_emcy_cob_entry(0x1005, 0));  // SYNC
}

}  // namespace
}  // namespace oegw::canopen
