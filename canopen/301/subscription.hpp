// Registrations that undo themselves: ObjectDictionary::add_observer and Object::add_write_hook
// return a Subscription; destroying (or reset()ing) it removes the callback. A service keeps its
// Subscriptions as members, so a destroyed service leaves nothing behind that captures `this`.
//
// The list a Subscription points to may die first (the Object was removed or replaced by
// add_var/add_array/add_record, or the ObjectDictionary was destroyed): the Subscription only
// holds a weak reference, so releasing it then does nothing.
//
// Callbacks may add or remove registrations (their own included) while the list is being
// called: a removed entry is skipped from then on, an added one is called from the next
// notification. Not thread-safe, like the services (one thread drives a stack).
#pragma once

#include <algorithm>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace oegw::canopen {

namespace detail {

class Unsubscribable {
 public:
  virtual ~Unsubscribable() = default;
  virtual void remove(std::uint64_t id) = 0;
};

template <class F>
class CallbackList final : public Unsubscribable {
 public:
  std::uint64_t add(F fn) {
    const std::uint64_t id = ++last_id_;
    if (depth_ > 0) {
      added_.push_back(Entry{id, std::move(fn), true});
    } else {
      entries_.push_back(Entry{id, std::move(fn), true});
    }
    return id;
  }

  void remove(std::uint64_t id) override {
    for (auto* v : {&entries_, &added_}) {
      for (auto& e : *v) {
        if (e.id == id) e.alive = false;  // never destroy a callable that may be running
      }
    }
    if (depth_ == 0) compact();
  }

  [[nodiscard]] bool empty() const { return entries_.empty() && added_.empty(); }
  [[nodiscard]] std::size_t size() const { return entries_.size(); }

  // Calls visit(fn) for each live entry in registration order, until visit returns true.
  // Returns whether one did.
  template <class Visit>
  bool for_each_until(Visit&& visit) {
    ++depth_;
    struct Guard {
      CallbackList* self;
      ~Guard() {
        if (--self->depth_ == 0) self->settle();
      }
    } guard{this};
    // Index-based: entries_ is not modified while depth_ > 0 (additions wait in added_).
    for (std::size_t i = 0; i < entries_.size(); ++i) {
      if (entries_[i].alive && visit(entries_[i].fn)) return true;
    }
    return false;
  }

 private:
  struct Entry {
    std::uint64_t id;
    F fn;
    bool alive;
  };

  void compact() {
    std::erase_if(entries_, [](const Entry& e) { return !e.alive; });
  }
  void settle() {
    for (auto& e : added_)
      if (e.alive) entries_.push_back(std::move(e));
    added_.clear();
    compact();
  }

  std::vector<Entry> entries_;
  std::vector<Entry> added_;  // registered during a notification
  std::uint64_t last_id_ = 0;
  int depth_ = 0;
};

}  // namespace detail

class [[nodiscard]] Subscription {
 public:
  Subscription() = default;
  Subscription(std::weak_ptr<detail::Unsubscribable> list, std::uint64_t id) : list_(std::move(list)), id_(id) {}
  Subscription(const Subscription&) = delete;
  Subscription& operator=(const Subscription&) = delete;
  Subscription(Subscription&& o) noexcept : list_(std::move(o.list_)), id_(std::exchange(o.id_, 0)) {}
  Subscription& operator=(Subscription&& o) noexcept {
    if (this != &o) {
      reset();
      list_ = std::move(o.list_);
      id_ = std::exchange(o.id_, 0);
    }
    return *this;
  }
  ~Subscription() { reset(); }

  // Removes the callback now (no-op if already released or if its list is gone).
  void reset() {
    if (id_ != 0) {
      if (auto l = list_.lock()) l->remove(id_);
    }
    list_.reset();
    id_ = 0;
  }
  // Lets go without removing: the callback then lives as long as its list. Only for callbacks
  // that capture nothing that could die first.
  void detach() {
    list_.reset();
    id_ = 0;
  }
  // True while the callback is registered (its list still exists).
  [[nodiscard]] bool active() const { return id_ != 0 && !list_.expired(); }

 private:
  std::weak_ptr<detail::Unsubscribable> list_;
  std::uint64_t id_ = 0;
};

// Several Subscriptions kept together by a service.
class Subscriptions {
 public:
  void add(Subscription s) { subs_.push_back(std::move(s)); }
  Subscriptions& operator+=(Subscription s) {
    add(std::move(s));
    return *this;
  }
  void clear() { subs_.clear(); }
  [[nodiscard]] std::size_t size() const { return subs_.size(); }

 private:
  std::vector<Subscription> subs_;
};

}  // namespace oegw::canopen
