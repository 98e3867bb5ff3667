#pragma once
// The laws a model names, chosen at run time among those composed at compile time: select_law,
// names_of and with_laws, for the contact pass (contact_pass.cpp) and its kernels' translation
// units (contact_kernel.hpp).
#include "systems/laws/law.hpp"
#include "systems/laws/mindlin.hpp"
#include "systems/laws/normal_laws.hpp"
#include "systems/laws/rolling.hpp"

#include <stdexcept>
#include <string>
#include <type_traits>

namespace sandcell {

// Calls fn(std::type_identity<L>{}) for the law of `list` for which match(L) holds; false if none.
template <class Match, class Fn, class... L>
bool select_law(LawList<L...>, Match match, Fn&& fn) {
  return ((match(std::type_identity<L>{}) ? (fn(std::type_identity<L>{}), true) : false) || ...);
}

template <class... L>
std::string names_of(LawList<L...>) {
  std::string out;
  ((out += (out.empty() ? "" : ", ") + std::string(L::name)), ...);
  return out;
}

// Calls fn(normal, tangential, rolling) with the model's laws as std::type_identity<Law> (and the
// rolling model as std::integral_constant); throws std::invalid_argument on an unregistered name.
template <class Fn>
void with_laws(const ContactSettings& contact, Fn&& fn) {
  const bool found = select_law(
      NormalLaws{}, [&](auto law) { return decltype(law)::type::name == contact.normal; },
      [&](auto normal) {
        select_law(
            TangentialLaws{}, [&](auto law) { return decltype(law)::type::id == contact.tangential; },
            [&](auto tangential) {
              const auto rolling = [&](auto roll) { fn(normal, tangential, roll); };
              switch (contact.rolling) {
                case RollingModel::none: rolling(std::integral_constant<RollingModel, RollingModel::none>{}); break;
                case RollingModel::epsd2: rolling(std::integral_constant<RollingModel, RollingModel::epsd2>{}); break;
                case RollingModel::epsd: rolling(std::integral_constant<RollingModel, RollingModel::epsd>{}); break;
                case RollingModel::cdt: rolling(std::integral_constant<RollingModel, RollingModel::cdt>{}); break;
              }
            });
      });
  if (!found)
    throw std::invalid_argument("contact.normal = \"" + contact.normal + "\": not a registered normal law (" +
                                names_of(NormalLaws{}) + ")");
}

}  // namespace sandcell
