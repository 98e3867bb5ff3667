#pragma once
// Scratch: rebuilt every step or every neighbour rebuild; never checkpointed. Buffers keep their
// capacity between steps so nothing is allocated inside a step once warmed up.
namespace sandcell {

struct Scratch {};

}  // namespace sandcell
