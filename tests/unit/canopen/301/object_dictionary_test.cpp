#include "canopen/301/object_dictionary.hpp"

#include <gtest/gtest.h>

using namespace oegw::canopen;

namespace {

TEST(ObjectDictionary, ReportsMissingObjectAndSubIndexSeparately) {
  ObjectDictionary od;
  od.add_var(0x1017, "Producer heartbeat time", DataType::Unsigned16, Access::ReadWrite, encode<std::uint16_t>(0));
  std::vector<std::uint8_t> out;
  EXPECT_EQ(od.read(0x1018, 0, out), SdoAbortCode::ObjectDoesNotExist);
  EXPECT_EQ(od.read(0x1017, 1, out), SdoAbortCode::SubIndexDoesNotExist);
  EXPECT_EQ(od.read(0x1017, 0, out), SdoAbortCode::None);
  EXPECT_EQ(out, (std::vector<std::uint8_t>{0, 0}));
}

TEST(ObjectDictionary, EnforcesAccessPerOrigin) {
  ObjectDictionary od;
  od.add_var(0x1000, "Device type", DataType::Unsigned32, Access::Const, encode<std::uint32_t>(0x000F0191));
  od.add_var(0x2000, "Secret", DataType::Unsigned8, Access::WriteOnly, {0});
  const std::uint8_t four[4] = {1, 2, 3, 4};
  EXPECT_EQ(od.write(0x1000, 0, four), SdoAbortCode::WriteOfReadOnly);
  EXPECT_EQ(od.get<std::uint32_t>(0x1000, 0), 0x000F0191u);
  std::vector<std::uint8_t> out;
  EXPECT_EQ(od.read(0x2000, 0, out), SdoAbortCode::ReadOfWriteOnly);
  EXPECT_EQ(od.write(0x1000, 0, four, Origin::Local), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::uint32_t>(0x1000, 0), 0x04030201u);
}

TEST(ObjectDictionary, SetEncodesToTheObjectsWidthLittleEndian) {
  ObjectDictionary od;
  od.add_var(0x2010, "I16", DataType::Integer16, Access::ReadWrite, {});
  od.add_var(0x2011, "U24", DataType::Unsigned24, Access::ReadWrite, {});
  od.add_var(0x2012, "U64", DataType::Unsigned64, Access::ReadWrite, {});
  od.add_var(0x2013, "R32", DataType::Real32, Access::ReadWrite, {});
  od.add_var(0x2014, "BOOLEAN", DataType::Boolean, Access::ReadWrite, {});
  od.reset_to_defaults(0x2010, 0x2014);
  EXPECT_EQ(od.set<std::int16_t>(0x2010, 0, -2), SdoAbortCode::None);
  EXPECT_EQ(od.find(0x2010, 0)->value, (std::vector<std::uint8_t>{0xFE, 0xFF}));
  EXPECT_EQ(od.set<std::uint32_t>(0x2011, 0, 0x00123456), SdoAbortCode::None);
  EXPECT_EQ(od.find(0x2011, 0)->value, (std::vector<std::uint8_t>{0x56, 0x34, 0x12}));
  EXPECT_EQ(od.set<int>(0x2012, 0, -1), SdoAbortCode::None);  // sign-extended to the width
  EXPECT_EQ(od.find(0x2012, 0)->value, std::vector<std::uint8_t>(8, 0xFF));
  EXPECT_EQ(od.set<float>(0x2013, 0, 1.5f), SdoAbortCode::None);
  EXPECT_EQ(od.find(0x2013, 0)->value, encode<float>(1.5f));
  EXPECT_EQ(od.set<bool>(0x2014, 0, true), SdoAbortCode::None);
  EXPECT_EQ(od.find(0x2014, 0)->value, (std::vector<std::uint8_t>{1}));
  EXPECT_EQ(od.set<std::uint8_t>(0x2015, 0, 1), SdoAbortCode::ObjectDoesNotExist);
}

TEST(ObjectDictionary, RefusesWrongLengthAndOutOfRangeWithoutChangingValue) {
  ObjectDictionary od;
  od.add_var(0x2001, "Limited", DataType::Integer16, Access::ReadWrite, encode<std::int16_t>(5));
  SubObject& s = *od.find(0x2001, 0);
  s.low = std::int64_t{-100};
  s.high = std::int64_t{100};
  const std::uint8_t three[3] = {1, 0, 0};
  const std::uint8_t one[1] = {1};
  EXPECT_EQ(od.write(0x2001, 0, three), SdoAbortCode::LengthTooHigh);
  EXPECT_EQ(od.write(0x2001, 0, one), SdoAbortCode::LengthTooLow);
  EXPECT_EQ(od.set<std::int16_t>(0x2001, 0, 101, Origin::Sdo), SdoAbortCode::ValueTooHigh);
  EXPECT_EQ(od.set<std::int16_t>(0x2001, 0, -101, Origin::Sdo), SdoAbortCode::ValueTooLow);
  EXPECT_EQ(od.get<std::int16_t>(0x2001, 0), 5);
  EXPECT_EQ(od.set<std::int16_t>(0x2001, 0, -100, Origin::Sdo), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::int16_t>(0x2001, 0), -100);
}

TEST(ObjectDictionary, HookRefusalLeavesValueAndObserversUntouched) {
  ObjectDictionary od;
  Object& o = od.add_var(0x2002, "Even only", DataType::Unsigned8, Access::ReadWrite, {2});
  const Subscription hook = o.add_write_hook([](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
    return (b[0] % 2) ? SdoAbortCode::InvalidValue : SdoAbortCode::None;
  });
  int notified = 0;
  const Subscription obs = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { ++notified; });
  EXPECT_EQ(od.set<std::uint8_t>(0x2002, 0, 3, Origin::Sdo), SdoAbortCode::InvalidValue);
  EXPECT_EQ(od.get<std::uint8_t>(0x2002, 0), 2);
  EXPECT_EQ(notified, 0);
  EXPECT_EQ(od.set<std::uint8_t>(0x2002, 0, 4, Origin::Sdo), SdoAbortCode::None);
  EXPECT_EQ(notified, 1);
}

TEST(ObjectDictionary, ArrayHasHighestSubIndexAndPdoRules) {
  ObjectDictionary od;
  od.add_array(0x6401, "Read analogue input 16-bit", DataType::Integer16, Access::ReadOnly, 3, encode<std::int16_t>(0),
               true);
  EXPECT_EQ(od.get<std::uint8_t>(0x6401, 0), 3);
  EXPECT_EQ(od.find(0x6401, 3)->value.size(), 2u);
  EXPECT_EQ(od.check_read(0x6401, 2, Origin::Pdo), SdoAbortCode::None);
  EXPECT_EQ(od.check_write(0x6401, 2, Origin::Pdo), SdoAbortCode::WriteOfReadOnly);
  EXPECT_EQ(od.check_read(0x6401, 0, Origin::Pdo), SdoAbortCode::CannotBeMapped);
}

TEST(ObjectDictionary, StringsAndDomainsHaveVariableLength) {
  ObjectDictionary od;
  od.add_var(0x1008, "Manufacturer device name", DataType::VisibleString, Access::Const, {'o', 'e', 'g', 'w'});
  od.add_var(0x2010, "Blob", DataType::Domain, Access::ReadWrite, {});
  od.find(0x2010, 0)->max_size = 1000;
  std::vector<std::uint8_t> big(1000, 0xAA);
  EXPECT_EQ(od.write(0x2010, 0, big), SdoAbortCode::None);
  big.push_back(0);
  EXPECT_EQ(od.write(0x2010, 0, big), SdoAbortCode::LengthTooHigh);
  EXPECT_EQ(od.find(0x2010, 0)->value.size(), 1000u);
  EXPECT_EQ(od.find(0x1008, 0)->value.size(), 4u);
}

TEST(ObjectDictionary, SignedDecodeSignExtendsOddWidths) {
  const std::uint8_t i24[3] = {0xFF, 0xFF, 0xFF};
  EXPECT_EQ(decode_signed(i24), -1);
  const std::uint8_t u24[3] = {0xFF, 0xFF, 0x7F};
  EXPECT_EQ(decode_signed(u24), 0x7FFFFF);
}

// find() answers from an index beside the tree: an object replaced, removed or added again is
// found as it is now, by every kind of builder.
TEST(ObjectDictionary, FindFollowsObjectsReplacedRemovedAndAddedAgain) {
  ObjectDictionary od;
  od.add_var(0x2000, "A", DataType::Unsigned8, Access::ReadWrite, {1});
  EXPECT_EQ(od.get<std::uint8_t>(0x2000, 0), 1);
  od.add_var(0x2000, "B", DataType::Unsigned8, Access::ReadWrite, {2});  // replaces A
  ASSERT_NE(od.find(0x2000), nullptr);
  EXPECT_EQ(od.find(0x2000)->name(), "B");
  EXPECT_EQ(od.get<std::uint8_t>(0x2000, 0), 2);
  EXPECT_TRUE(od.remove(0x2000));
  EXPECT_EQ(od.find(0x2000), nullptr);
  EXPECT_EQ(od.find(0x2000, 0), nullptr);
  EXPECT_FALSE(od.remove(0x2000));
  std::vector<std::uint8_t> out;
  EXPECT_EQ(od.read(0x2000, 0, out), SdoAbortCode::ObjectDoesNotExist);
  od.add_record_member(0x2000, 2, "member", DataType::Unsigned16, Access::ReadWrite, {0x34, 0x12});
  ASSERT_NE(od.find(0x2000, 2), nullptr);
  EXPECT_EQ(od.get<std::uint16_t>(0x2000, 2), 0x1234);
  od.add_array(0x2001, "C", DataType::Unsigned8, Access::ReadWrite, 3, {7});
  EXPECT_EQ(od.get<std::uint8_t>(0x2001, 3), 7);
  EXPECT_EQ(od.objects().size(), 2u);
  for (const auto& [index, obj] : od.objects()) EXPECT_EQ(od.find(index), &obj) << index;
}

// A Slot (a sub-object resolved once): set_local() writes as set<>(…, Origin::Local) does —
// width, limits, hooks, observers —, get() reads as get() by index does, and both follow the object when it is
// replaced, removed and added again (the layout counted), never writing into a freed one.
TEST(ObjectDictionary, ASlotWritesAsSetDoesAndFollowsTheLayout) {
  ObjectDictionary od;
  od.add_var(0x6401, "Axis", DataType::Integer16, Access::ReadOnly, encode<std::int16_t>(0), true);
  od.find(0x6401, 0)->high = std::int64_t{1000};
  int notified = 0;
  const Subscription obs = od.add_observer([&](std::uint16_t index, std::uint8_t sub, Origin origin) {
    EXPECT_EQ(index, 0x6401);
    EXPECT_EQ(sub, 0);
    EXPECT_EQ(origin, Origin::Local);
    ++notified;
  });
  ObjectDictionary::Slot slot{0x6401, 0};
  ASSERT_EQ(od.resolve(slot), od.find(0x6401, 0));
  EXPECT_EQ(od.set_local(slot, -300), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::int16_t>(0x6401, 0), -300) << "two bytes, little endian, read-only to the bus only";
  EXPECT_EQ(od.get<std::int16_t>(slot), -300) << "get() through the slot reads the value live";
  EXPECT_EQ(notified, 1);
  EXPECT_EQ(od.set_local(slot, 1001), SdoAbortCode::ValueTooHigh);
  EXPECT_EQ(od.get<std::int16_t>(0x6401, 0), -300);
  EXPECT_EQ(notified, 1);
  const auto before = od.layout();
  od.add_var(0x6401, "Axis again", DataType::Integer32, Access::ReadOnly, encode<std::int32_t>(0));  // replaced
  EXPECT_NE(od.layout(), before);
  EXPECT_EQ(od.set_local(slot, 70000), SdoAbortCode::None);
  EXPECT_EQ(od.get<std::int32_t>(0x6401, 0), 70000) << "the new object's four bytes";
  EXPECT_EQ(od.get<std::int32_t>(slot), 70000) << "get() through the slot follows the replacement";
  EXPECT_EQ(od.resolve(slot), od.find(0x6401, 0));
  EXPECT_TRUE(od.remove(0x6401));
  EXPECT_EQ(od.resolve(slot), nullptr);
  EXPECT_EQ(od.get<std::int32_t>(slot), 0) << "a removed entry reads 0, as get() by index";
  EXPECT_EQ(od.set_local(slot, 1), SdoAbortCode::ObjectDoesNotExist);
  od.add_record_member(0x6401, 1, "member", DataType::Unsigned8, Access::ReadWrite, {0});
  EXPECT_EQ(od.set_local(slot, 1), SdoAbortCode::None) << "sub-index 0 of the record";
  EXPECT_EQ(od.get<std::uint8_t>(0x6401, 0), 1);
  ObjectDictionary::Slot absent{0x6401, 9};
  EXPECT_EQ(od.set_local(absent, 1), SdoAbortCode::SubIndexDoesNotExist);
}

// Subscriptions (observer and hook lifetime): a callback is removed with its handle.
TEST(ObjectDictionarySubscription, ObserverAndHookRemovedWhenHandleDies) {
  ObjectDictionary od;
  Object& o = od.add_var(0x2002, "Even only", DataType::Unsigned8, Access::ReadWrite, {2});
  int notified = 0;
  {
    const Subscription hook = o.add_write_hook([](Object&, std::uint8_t, std::span<const std::uint8_t> b, Origin) {
      return (b[0] % 2) ? SdoAbortCode::InvalidValue : SdoAbortCode::None;
    });
    const Subscription obs = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { ++notified; });
    EXPECT_EQ(od.observer_count(), 1u);
    EXPECT_EQ(o.write_hook_count(), 1u);
    EXPECT_EQ(od.set<std::uint8_t>(0x2002, 0, 3, Origin::Sdo), SdoAbortCode::InvalidValue);
    EXPECT_EQ(od.set<std::uint8_t>(0x2002, 0, 4, Origin::Sdo), SdoAbortCode::None);
    EXPECT_EQ(notified, 1);
  }
  EXPECT_EQ(od.observer_count(), 0u);
  EXPECT_EQ(o.write_hook_count(), 0u);
  EXPECT_EQ(od.set<std::uint8_t>(0x2002, 0, 3, Origin::Sdo), SdoAbortCode::None);
  EXPECT_EQ(notified, 1);
}

TEST(ObjectDictionarySubscription, ReleasingAfterObjectReplacedOrRemovedIsSafe) {
  ObjectDictionary od;
  Subscription a = od.add_var(0x2000, "A", DataType::Unsigned8, Access::ReadWrite, {0})
                       .add_write_hook([](Object&, std::uint8_t, std::span<const std::uint8_t>, Origin) {
                         return SdoAbortCode::InvalidValue;
                       });
  Subscription b = od.add_var(0x2001, "B", DataType::Unsigned8, Access::ReadWrite, {0})
                       .add_write_hook([](Object&, std::uint8_t, std::span<const std::uint8_t>, Origin) {
                         return SdoAbortCode::InvalidValue;
                       });
  EXPECT_TRUE(a.active());
  // Replacing the object drops its hooks: the new object accepts the write.
  od.add_var(0x2000, "A again", DataType::Unsigned8, Access::ReadWrite, {0});
  EXPECT_FALSE(a.active());
  EXPECT_EQ(od.set<std::uint8_t>(0x2000, 0, 1, Origin::Sdo), SdoAbortCode::None);
  EXPECT_TRUE(od.remove(0x2001));
  EXPECT_FALSE(b.active());
  a.reset();
  b.reset();
  a.reset();  // twice: still nothing
}

TEST(ObjectDictionarySubscription, HandleMayOutliveDictionary) {
  Subscription obs;
  Subscription hook;
  {
    ObjectDictionary od;
    obs = od.add_observer([](std::uint16_t, std::uint8_t, Origin) {});
    hook = od.add_var(0x2000, "A", DataType::Unsigned8, Access::ReadWrite, {0})
               .add_write_hook(
                   [](Object&, std::uint8_t, std::span<const std::uint8_t>, Origin) { return SdoAbortCode::None; });
    EXPECT_TRUE(obs.active());
  }
  EXPECT_FALSE(obs.active());
  EXPECT_FALSE(hook.active());
}  // destructors run here: must not touch the dead dictionary

TEST(ObjectDictionarySubscription, CallbacksMayUnsubscribeAndSubscribeDuringNotification) {
  ObjectDictionary od;
  od.add_var(0x2000, "A", DataType::Unsigned8, Access::ReadWrite, {0});
  int first = 0;
  int second = 0;
  int late = 0;
  Subscription s2;
  Subscription s3;
  Subscription s1 = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) {
    ++first;
    s2.reset();  // removes the next observer before it runs
    if (!s3.active())
      s3 = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { ++late; });  // from the next write on
  });
  s2 = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { ++second; });
  EXPECT_EQ(od.set<std::uint8_t>(0x2000, 0, 1), SdoAbortCode::None);
  EXPECT_EQ(first, 1);
  EXPECT_EQ(second, 0);
  EXPECT_EQ(late, 0);
  EXPECT_EQ(od.set<std::uint8_t>(0x2000, 0, 2), SdoAbortCode::None);
  EXPECT_EQ(first, 2);
  EXPECT_EQ(late, 1);
  EXPECT_EQ(od.observer_count(), 2u);
  // An observer that removes itself.
  Subscription self;
  self = od.add_observer([&](std::uint16_t, std::uint8_t, Origin) { self.reset(); });
  EXPECT_EQ(od.set<std::uint8_t>(0x2000, 0, 3), SdoAbortCode::None);
  EXPECT_FALSE(self.active());
  EXPECT_EQ(od.observer_count(), 2u);
}

}  // namespace
