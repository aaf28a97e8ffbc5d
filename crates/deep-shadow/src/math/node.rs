//! The list element of Fürst et al. Listing 1.1, the layout both twins share: the CPU twin's
//! lists hold it and the engine path's element buffer is read back into it; mirrored field for
//! field by `Node` in `node.wgsl`.
//! `deep_shadow.wgsl`'s stages.

/// "No element": the end of a list, an empty head, a missing neighbour link.
pub const NIL: u32 = u32::MAX;

/// One list element (Fürst et al. §1.3.1, Listing 1.1), 32 bytes.
///
/// - `depth`: linear light-space z of the fragment (docs/methods.md §1), unbiased (the bias is
///   applied at the receiver).
/// - `alpha`: the fragment's opacity `alpha_i` (the mesh's `opacity`, 1 for opaque meshes).
/// - `tau`: after processing (§1.3.2), the cumulative transmittance through this element,
///   `tau_k = prod_{i <= k} (1 - alpha_i)` (Eq. 1.1), over the list sorted by depth.
/// - `next`, `prev`: the doubly linked list in depth order (`prev` is set while processing).
/// - `right`, `upper`: the depth-nearest elements of the lists of texels (i+1, j) and (i, j+1)
///   (§1.3.3), or [`NIL`].
#[repr(C)]
#[cfg_attr(feature = "gpu", derive(bytemuck::Pod, bytemuck::Zeroable))]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Linear light-space depth z.
    pub(crate) depth: f32,
    /// Opacity alpha.
    pub(crate) alpha: f32,
    /// Cumulative transmittance `tau_k` (Eq. 1.1) after processing; 1 before.
    pub(crate) tau: f32,
    /// Next element (deeper after sorting), or [`NIL`].
    pub(crate) next: u32,
    /// Previous element, or [`NIL`].
    pub(crate) prev: u32,
    /// Depth-nearest element in the right neighbour's list, or [`NIL`].
    pub(crate) right: u32,
    /// Depth-nearest element in the upper neighbour's list, or [`NIL`].
    pub(crate) upper: u32,
    /// Padding to 32 bytes.
    pub(crate) _pad0: u32,
}

impl Node {
    /// A fresh element as inserted by the build (unsorted, unlinked).
    pub fn fragment(depth: f32, alpha: f32, next: u32) -> Self {
        Node {
            depth,
            alpha,
            tau: 1.0,
            next,
            prev: NIL,
            right: NIL,
            upper: NIL,
            _pad0: 0,
        }
    }
    /// Linear light-space depth z.
    pub fn depth(&self) -> f32 {
        self.depth
    }
    /// Opacity alpha.
    pub fn alpha(&self) -> f32 {
        self.alpha
    }
    /// Cumulative transmittance `tau_k` (Eq. 1.1) after processing; 1 before.
    pub fn tau(&self) -> f32 {
        self.tau
    }
    /// Next element (deeper after sorting), or [`NIL`].
    pub fn next(&self) -> u32 {
        self.next
    }
    /// Previous element, or [`NIL`].
    pub fn prev(&self) -> u32 {
        self.prev
    }
    /// Depth-nearest element in the right neighbour's list, or [`NIL`].
    pub fn right(&self) -> u32 {
        self.right
    }
    /// Depth-nearest element in the upper neighbour's list, or [`NIL`].
    pub fn upper(&self) -> u32 {
        self.upper
    }
}
