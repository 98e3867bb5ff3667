// The owner partition's halo (systems/halo.hpp): what it maps, what it copies, and that a world
// stepped through it is bitwise the world stepped without it.
#include "components/contacts.hpp"
#include "engine/world.hpp"
#include "support/scenes.hpp"
#include "systems/catalogue.hpp"
#include "systems/force_gather.hpp"
#include "systems/halo.hpp"
#include "systems/pair_list.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <set>

using namespace sandcell;

namespace {
// A dense jammed lattice of 12^3 spheres (every lattice neighbour overlaps), velocities random, so
// that pairs cross every share boundary and forces, torques and histories are all non-zero.
State dense_scene(const Model& model) {
  return test::jittered_lattice(model, 12, 1.0e-3, 0.52e-3, 0.56e-3, 0.01e-3, 0.05, 20.0, 91);
}
}  // namespace

TEST_CASE("owner partition: the halo maps every crossing pair and copies exactly what the pass reads") {
  Model model = test::quartz_model(2e-8, 0.1e-3);
  model.contact.sort_interval = 10;  // Morton order, so that the shares are compact regions
  const State start = dense_scene(model);
  World serial(model, start, systems_for(model), ExecutorConfig{Backend::serial, 1});
  serial.step(25);
  for (int threads : {2, 3, 5}) {
    CAPTURE(threads);
    World w(model, start, systems_for(model), ExecutorConfig{Backend::tbb, threads, Partition::owner});
    w.step(25);
    // Bitwise the serial world: the halo moves copies, never changes a value or an order of sums.
    CHECK(first_difference(w.state().particles, serial.state().particles) == "");
    CHECK(first_difference(w.state().contacts, serial.state().contacts) == "");

    const Halo& halo = w.scratch().own<Halo>();
    const State& s = w.state();
    const ContactPairs& pairs = s.contacts.pairs;
    const std::size_t n = s.particles.size(), m = pairs.size();
    REQUIRE(halo.active);
    REQUIRE(halo.n == n);
    REQUIRE(halo.m == m);
    CHECK(halo.particles.count == static_cast<std::size_t>(threads));
    // Every pair is in exactly one pair share, and (but for the fewer than 64 pairs of a block cut
    // at a share boundary) its i is in the matching particle share.
    std::size_t misplaced = 0, crossing = 0;
    for (std::size_t k = 0; k < m; ++k) {
      const std::size_t s_pair = share_of(halo.pairs, k);
      if (share_of(halo.particles, pairs.i[k]) != s_pair) ++misplaced;
      const std::uint32_t j = pairs.j[k], jh = halo.pj[k];
      if (share_of(halo.particles, j) == s_pair) {
        CHECK(jh == j);
      } else {
        ++crossing;
        REQUIRE(jh >= n);
        CHECK(halo.ghost_of[jh - n] == j);
      }
    }
    CHECK(misplaced < 64 * (halo.particles.count - 1));
    CHECK(crossing > 0);
    // The blocks of 64 pairs the contact pass runs with ghosts are exactly those with one.
    REQUIRE(halo.ghost_block.size() == (m + 63) / 64);
    std::size_t ghost_blocks = 0;
    for (std::size_t blk = 0; blk < halo.ghost_block.size(); ++blk) {
      bool any = false;
      for (std::size_t k = blk * 64; k < std::min(m, blk * 64 + 64); ++k) any |= halo.pj[k] >= n;
      CHECK(static_cast<bool>(halo.ghost_block[blk]) == any);
      ghost_blocks += any;
    }
    CHECK(ghost_blocks > 0);
    // The ghosts hold this step's positions (taken after the drift; the closing kick changes only
    // velocities), and each is exported by the share owning its particle.
    for (std::size_t e = 0; e < halo.exports.count; ++e)
      for (std::size_t q = halo.exports.bounds[e]; q < halo.exports.bounds[e + 1]; ++q)
        CHECK(share_of(halo.particles, halo.ghost_of[halo.export_ghost[q]]) == e);
    std::size_t stale = 0;
    for (std::size_t g = 0; g < halo.ghost_of.size(); ++g)
      if (halo.gx[g] != s.particles.position[halo.ghost_of[g]]) ++stale;
    CHECK(stale == 0);
    // Slots: one per pair whose j another share gathers, holding the pair's force and torque on j.
    std::size_t slot_pairs = 0;
    for (std::size_t k = 0; k < m; ++k)
      if (share_of(halo.particles, pairs.j[k]) != share_of(halo.pairs, k)) ++slot_pairs;
    CHECK(halo.slot_pair.size() == slot_pairs);
    std::set<std::uint32_t> slots(halo.slot_of.begin(), halo.slot_of.end());
    CHECK(slots.size() == halo.slot_of.size());
    for (std::size_t q = 0; q < halo.slot_pair.size(); ++q) {
      CHECK(halo.sf[halo.slot_of[q]] == s.contacts.forces.force[halo.slot_pair[q]]);
      CHECK(halo.st[halo.slot_of[q]] == s.contacts.forces.torque_j[halo.slot_pair[q]]);
    }
    // The gather's entries: the index's, with exactly the slot pairs replaced by m + slot.
    const GatherIndex& index = w.scratch().own<GatherIndex>();
    std::size_t replaced = 0;
    for (std::size_t q = 0; q < index.j_entry.size(); ++q) {
      if (halo.j_entry[q] == index.j_entry[q]) continue;
      ++replaced;
      REQUIRE(halo.j_entry[q] >= m);
    }
    CHECK(replaced == slot_pairs);
  }
}

TEST_CASE("only the owner partition with more than one thread builds a halo") {
  Model model = test::quartz_model(2e-8, 0.1e-3);
  const State start = dense_scene(model);
  for (const ExecutorConfig cfg :
       {ExecutorConfig{Backend::tbb, 1, Partition::owner}, ExecutorConfig{Backend::serial, 4},
        ExecutorConfig{Backend::tbb, 2, Partition::dynamic}, ExecutorConfig{Backend::tbb, 2, Partition::fixed}}) {
    World w(model, start, systems_for(model), cfg);
    w.step(3);
    CHECK_FALSE(w.scratch().own<Halo>().active);
  }
}

TEST_CASE("adaptive partition: switching between owner and dynamic between steps keeps every bit") {
  // Batches of 2 steps and a hold of one step (1e-6 of the trial): a trial every 9 steps whatever
  // the step times, each with a return to owner, so the halo is dropped and rebuilt many times
  // inside one list (and across rebuilds of it).
  Model model = test::quartz_model(2e-8, 0.1e-3);
  model.contact.sort_interval = 10;
  const State start = dense_scene(model);
  World serial(model, start, systems_for(model), ExecutorConfig{Backend::serial, 1});
  serial.step(40);
  for (int threads : {2, 3}) {
    CAPTURE(threads);
    World w(model, start, systems_for(model),
            ExecutorConfig{Backend::tbb, threads, Partition::adaptive, AdaptiveSettings{0.0, 2, 1e-6}});
    // After each step the halo is that step's partition's: built under owner (also on a return from
    // dynamic within the same list), dropped under dynamic.
    int mismatched = 0, returns = 0;
    Partition last = Partition::owner;
    for (int k = 0; k < 40; ++k) {
      const Partition used = w.executor().active_partition();
      w.step(1);
      if (w.scratch().own<Halo>().active != (used == Partition::owner)) ++mismatched;
      if (used == Partition::owner && last == Partition::dynamic) ++returns;
      last = used;
    }
    CHECK(mismatched == 0);
    CHECK(returns >= 4);
    CHECK(first_difference(w.state().particles, serial.state().particles) == "");
    CHECK(first_difference(w.state().contacts, serial.state().contacts) == "");
    const PartitionSteps& st = w.executor().partition_steps();
    CHECK(st.owner + st.dynamic == 40);
    CHECK(st.owner > 0);
    CHECK(st.dynamic > 0);
    CHECK(st.switches >= 4);
  }
}

TEST_CASE("force gather visiting orders: sorted, array and adaptive keep every bit, with and without a halo") {
  // The order changes which particle a thread sums when, never a sum's order (force_gather.hpp):
  // each world must be bitwise the serial world in the sorted order. 40 steps hold the adaptive
  // trial (2 x 16 calls, the setup's included) and the start of its hold.
  Model model = test::quartz_model(2e-8, 0.1e-3);
  model.contact.sort_interval = 10;
  const State start = dense_scene(model);
  World serial(model, start, systems_for(model), ExecutorConfig{Backend::serial, 1, Partition::owner, {}, VisitOrder::sorted});
  serial.step(40);
  CHECK(serial.scratch().own<GatherTrials>().array_calls == 0);
  for (const VisitOrder order : {VisitOrder::sorted, VisitOrder::array, VisitOrder::adaptive})
    for (const Partition partition : {Partition::owner, Partition::dynamic}) {
      CAPTURE(visit_order_name(order));
      CAPTURE(partition_name(partition));
      World w(model, start, systems_for(model), ExecutorConfig{Backend::tbb, 2, partition, {}, order});
      w.step(40);
      CHECK(w.scratch().own<Halo>().active == (partition == Partition::owner));
      CHECK(first_difference(w.state().particles, serial.state().particles) == "");
      CHECK(first_difference(w.state().contacts, serial.state().contacts) == "");
      const GatherTrials& t = w.scratch().own<GatherTrials>();
      CHECK(t.sorted_calls + t.array_calls == 41);  // the setup's call and one per step
      if (order == VisitOrder::adaptive) {
        // The trial alternated the two, 16 calls each, and then held one of them.
        CHECK(t.trials == 1);
        CHECK(std::min(t.sorted_calls, t.array_calls) >= GatherTrials::k_trial);
        CHECK_FALSE(t.in_trial);
        CHECK((t.array ? t.array_calls : t.sorted_calls) == GatherTrials::k_trial + 41 - 2 * GatherTrials::k_trial);
      } else {
        CHECK((order == VisitOrder::array ? t.sorted_calls : t.array_calls) == 0);
        CHECK(t.trials == 0);
      }
    }
}

TEST_CASE("visit order names: each order's name gives it back, and nothing else is a name") {
  for (const VisitOrder v : {VisitOrder::sorted, VisitOrder::array, VisitOrder::adaptive})
    CHECK(visit_order_from_name(visit_order_name(v)) == v);
  CHECK_FALSE(visit_order_from_name("Sorted").has_value());
  CHECK_FALSE(visit_order_from_name("").has_value());
}

TEST_CASE("force gather trials: the order with the smaller median time is held, then tried again") {
  // Chosen times (GatherTrials without the clock): in the trial the calls alternate sorted, array.
  // A median, so one slow outlier per order does not decide; after k_hold calls a new trial starts.
  const auto run_trial = [](GatherTrials& t, double sorted_s, double array_s, double outlier_s) {
    for (std::uint32_t k = 0; k < 2 * GatherTrials::k_trial; ++k) {
      REQUIRE(t.in_trial);
      const bool array = t.next_array();
      CHECK(array == (k % 2 == 1));
      t.count(array);
      t.record(k < 2 ? outlier_s : array ? array_s : sorted_s);  // calls 0, 1: one outlier in each order
    }
  };
  GatherTrials t;
  run_trial(t, 2.0e-3, 1.0e-3, 9.0);  // array faster, each order's first call a 9 s outlier
  CHECK_FALSE(t.in_trial);
  CHECK(t.array);
  CHECK(t.trials == 1);
  for (std::uint32_t k = 0; k < GatherTrials::k_hold; ++k) {
    CHECK(t.next_array());  // the hold runs the winner
    t.count(true);
    t.record(5.0);          // times in the hold decide nothing
  }
  CHECK(t.in_trial);
  run_trial(t, 1.0e-3, 3.0e-3, 0.0);  // now sorted faster, outliers fast: the medians still decide
  CHECK_FALSE(t.array);
  CHECK(t.trials == 2);
  CHECK(t.sorted_calls == 2 * GatherTrials::k_trial);  // two trials, 16 each
  CHECK(t.array_calls == 2 * GatherTrials::k_trial + GatherTrials::k_hold);
}
