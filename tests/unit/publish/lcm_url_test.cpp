// The mapping file's rule for publish.lcm.url (publish/lcm_url.hpp): no link-local group
// (224.0.0.0/24) with a ttl above 0; the group read as liblcm reads it, with inet_aton(3).
#include "publish/lcm_url.hpp"

#include <arpa/inet.h>
#include <netinet/in.h>

#include <gtest/gtest.h>

namespace oegw::gateway {
namespace {

TEST(LcmUrl, HostLocalDefaultAndAdministrativelyScopedGroupsPass) {
  EXPECT_FALSE(publish::link_local_send("udpm://224.0.0.1:7667?ttl=0"));
  EXPECT_FALSE(publish::link_local_send("udpm://224.0.0.1:7667"));  // no ttl: 0
  EXPECT_FALSE(publish::link_local_send("udpm://224.0.0.1"));
  EXPECT_FALSE(publish::link_local_send("udpm://239.255.76.67:7667?ttl=1"));
  EXPECT_FALSE(publish::link_local_send("udpm://224.0.1.1:7667?ttl=1"));          // not 224.0.0.0/24
  EXPECT_FALSE(publish::link_local_send("udpm://224.0.0.251:7667?ttl=2&ttl=0"));  // the last ttl counts
  EXPECT_FALSE(publish::link_local_send("file:///tmp/x?ttl=1"));
  EXPECT_FALSE(publish::link_local_send("udpm://not-an-address:7667?ttl=1"));
}

TEST(LcmUrl, LinkLocalGroupWithATtlIsReportedWithTheGroupAndTheTtl) {
  auto s = publish::link_local_send("udpm://224.0.0.1:7667?ttl=1");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->group, "224.0.0.1");
  EXPECT_EQ(s->ttl, "1");
  s = publish::link_local_send("udpm://224.0.0.251:7667?recv_buf_size=1024&ttl=0&ttl=");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->group, "224.0.0.251");
  EXPECT_EQ(s->ttl, "");  // only exactly "0" keeps it on the host
  s = publish::link_local_send("udpm://0xE0000005?ttl=00");
  ASSERT_TRUE(s);
  EXPECT_EQ(s->group, "224.0.0.5");
  EXPECT_EQ(s->ttl, "00");
}

// Who else can send to a subscriber of the URL: what `oegw check` warns about when LCM carries
// commands (mapping/deployment.cpp).
TEST(LcmUrl, OnlyTheAllHostsGroupWithTtl0AndTheInProcessProvidersStayOnThisHost) {
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("udpm://224.0.0.1:7667?ttl=0"));
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("udpm://224.0.0.1:7667"));               // no ttl: 0
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("udpm://0xE0000001:7667?ttl=1&ttl=0"));  // the last ttl counts
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("memq://"));
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("file:///tmp/x.lcmlog?mode=r"));
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("tcpq://127.0.0.1:7700"));
  EXPECT_FALSE(publish::lcm_reaches_beyond_host("tcpq://localhost:7700"));

  auto why = publish::lcm_reaches_beyond_host("udpm://239.255.76.67:7667?ttl=1");
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("its ttl 1 makes it a network's group"), std::string::npos) << *why;
  why = publish::lcm_reaches_beyond_host("udpm://224.0.0.1:7667?ttl=");
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("its ttl  makes"), std::string::npos) << *why;          // only exactly "0" is 0
  why = publish::lcm_reaches_beyond_host("udpm://239.255.76.67:7667?ttl=0");  // ttl 0, but announced by IGMP
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("its group 239.255.76.67 is joined on the interface the routing table picks"), std::string::npos)
      << *why;
  why = publish::lcm_reaches_beyond_host("udpm://");  // liblcm's default group
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("239.255.76.67"), std::string::npos) << *why;
  why = publish::lcm_reaches_beyond_host("tcpq://10.0.0.5:7700");
  ASSERT_TRUE(why);
  EXPECT_NE(why->find("the LCM server 10.0.0.5"), std::string::npos) << *why;
  EXPECT_TRUE(publish::lcm_reaches_beyond_host("mpudpm://239.255.76.67:7667"));  // not liblcm 1.3.1's
}

TEST(LcmUrl, AddressFormsAreThoseOfInetAton) {
  for (const char* text : {"224.0.0.1",
                           "224.0.1",
                           "224.1",
                           "3758096385",
                           "0xE0000001",
                           "0340.0.0.1",
                           "224.0x0.0.1",
                           "224.0.0.1 trailing",
                           "224.0.0.1\tx",
                           "224.0.65535",
                           "224.0.65536",
                           "224.16777215",
                           "224.0.0.256",
                           "224.0.0.1.1",
                           "224.0.0.09",
                           "224.0.0.08",
                           "224.00.0.1",
                           "224.0x.0.1",
                           "+224.0.0.1",
                           " 224.0.0.1",
                           "",
                           ".",
                           "224.",
                           "224..1",
                           "224.0.0.",
                           "0x",
                           "0x1G",
                           "4294967295",
                           "4294967296",
                           "99999999999999999999999",
                           "0xFFFFFFFF",
                           "0x100000000",
                           "1.2.3.4x",
                           "1.2.3.4\n",
                           "255.255.255.255",
                           "0",
                           "00",
                           "0.0.0.0",
                           "224.0.0.1:7667"}) {
    in_addr a{};
    const bool ok = ::inet_aton(text, &a) != 0;
    const auto mine = publish::parse_inet_aton(text);
    ASSERT_EQ(mine.has_value(), ok) << "'" << text << "'";
    if (ok) {
      EXPECT_EQ(*mine, ntohl(a.s_addr)) << "'" << text << "'";
      EXPECT_EQ(publish::dotted_quad(*mine), ::inet_ntoa(a)) << "'" << text << "'";
    }
  }
  // The text ends at a NUL, as for the C function.
  EXPECT_EQ(publish::parse_inet_aton(std::string_view("224.0.0.1\0x", 11)), 0xE0000001u);
}

}  // namespace
}  // namespace oegw::gateway
