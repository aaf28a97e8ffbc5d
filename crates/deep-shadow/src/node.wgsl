// A list element of the deep shadow map (mirrors math/node.rs Node field for field) and the
// empty-list index NIL (shared::NIL, set from Rust as a pipeline override): the part both
// deep-shadow modules (the frame's and the insert pass's) take before their own.
override NIL: u32;

struct Node {
    depth: f32,
    alpha: f32,
    tau: f32,
    next: u32,
    prev: u32,
    right: u32,
    upper: u32,
    _pad0: u32,
}
