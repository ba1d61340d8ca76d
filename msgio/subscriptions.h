#ifndef ROOMFIX_MSGIO_SUBSCRIPTIONS_H_
#define ROOMFIX_MSGIO_SUBSCRIPTIONS_H_

#include <vector>

#include "msgio/bus.h"

namespace roomfix {

// The subscriptions a node holds, ended when it is destroyed. A handler that
// captures `this` must not outlive its object: the bus would call it on freed
// memory with the next message (LoggerNode did). A node declares this member
// last, so it is destroyed first, before anything its handlers use; like
// every Bus call, on the thread that calls bus->Handle.
class Subscriptions {
 public:
  explicit Subscriptions(Bus* bus) : bus_(bus) {}
  ~Subscriptions() { Clear(); }
  Subscriptions(const Subscriptions&) = delete;
  Subscriptions& operator=(const Subscriptions&) = delete;

  // Keeps an id that bus->Subscribe or SubscribeRaw returned.
  void Add(SubscriptionId id) { ids_.push_back(id); }
  // Unsubscribes every id held; a second call does nothing.
  void Clear() {
    for (SubscriptionId id : ids_) bus_->Unsubscribe(id);
    ids_.clear();
  }

 private:
  Bus* bus_;
  std::vector<SubscriptionId> ids_;
};

}  // namespace roomfix

#endif  // ROOMFIX_MSGIO_SUBSCRIPTIONS_H_
