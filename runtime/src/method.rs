//! The rendering methods: their names, their layouts and what a k-buffer method's frame may
//! reserve. Below the frame, the plan and the GPU's passes, which all name a method.

use crate::budget::{self, Layout, Occupancy};
use crate::error::{Error, Result};

/// Rendering methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Exact A-buffer: every fragment sorted and blended (the reference image).
    Abuffer,
    /// Fixed k-buffer: one k for every pixel.
    Fkb,
    /// Variable k-buffer with the importance maps of paper 002.
    Vkb,
    /// Deep k-buffer: k from the network's importance.
    Dkb,
    /// The optimal allocation (quality ceiling of any k-buffer allocation with a tail a pixel).
    Optimal,
    /// The optimal allocation of a k-buffer whose tails share its slots' pool, VKB's and DKB's
    /// layout ([`crate::alloc::ErrorCurves::pooled`]): the least error they can reach with F
    /// slots. Its memory is DKB's, so at equal bytes it gets DKB's F. Computed on the CPU only
    /// (the GPU's uploaded k keeps a tail a pixel).
    OptimalPooled,
    /// The paper's backward greedy as printed (heap keyed by the new error).
    GreedyPaper,
    /// The backward greedy keyed by the error increase.
    GreedyIncrease,
    /// Multi-layer alpha blending with as many rows per pixel as FKB has slots.
    Mlab,
    /// Weighted blended OIT (McGuire and Bavoil 2013): no slots, no order, fixed memory.
    Wboit,
    /// Moment-based OIT (Munstermann et al. 2018), 4, 6 or 8 power moments
    /// ([`crate::composite::MboitParams`]): no slots, no order, fixed memory.
    Mboit,
    /// A budgeted per-pixel linked list, as Bevy ships it: fragments appended first come, first
    /// served until the frame's F nodes are spent (the rest dropped), each pixel's nearest
    /// [`crate::frame::Options::list_sorted`] sorted and blended at resolve, the rest as a hybrid tail.
    /// Order-dependent where F truncates.
    LinkedList,
}

impl Method {
    pub const ALL: [Method; 12] = [
        Method::Abuffer,
        Method::Fkb,
        Method::Vkb,
        Method::Dkb,
        Method::Optimal,
        Method::OptimalPooled,
        Method::GreedyPaper,
        Method::GreedyIncrease,
        Method::Mlab,
        Method::Wboit,
        Method::Mboit,
        Method::LinkedList,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Method::Abuffer => "abuffer",
            Method::Fkb => "fkb",
            Method::Vkb => "vkb",
            Method::Dkb => "dkb",
            Method::Optimal => "optimal",
            Method::OptimalPooled => "optimal-pooled",
            Method::GreedyPaper => "greedy-paper",
            Method::GreedyIncrease => "greedy-increase",
            Method::Mlab => "mlab",
            Method::Wboit => "wboit",
            Method::Mboit => "mboit",
            Method::LinkedList => "linked-list",
        }
    }

    pub fn parse(s: &str) -> Result<Method> {
        Method::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                let names: Vec<_> = Method::ALL.iter().map(|m| m.name()).collect();
                Error::Invalid(format!(
                    "unknown method '{s}': expected one of {}",
                    names.join(", ")
                ))
            })
    }

    /// What the method is, in a line: `dhoit --help` lists every method with it
    /// ([`help`]).
    pub fn summary(self) -> &'static str {
        match self {
            Method::Abuffer => "exact reference",
            Method::Fkb => "fixed k-buffer",
            Method::Vkb => "importance-map variable k-buffer",
            Method::Dkb => "deep k-buffer: the network's importance",
            Method::Optimal => "the optimal allocation",
            Method::OptimalPooled => {
                "the optimal allocation in VKB's and DKB's layout, their tails pooled; CPU only"
            }
            Method::GreedyPaper => "the paper's backward greedy, its heap keyed by the new error",
            Method::GreedyIncrease => "the backward greedy, its heap keyed by the error's increase",
            Method::Mlab => "multi-layer alpha blending",
            Method::Wboit => {
                "weighted blended OIT, McGuire and Bavoil 2013: one pass into an RGBA16F and an \
                 R8 target, no sorting"
            }
            Method::Mboit => {
                "moment-based OIT, Munstermann et al. 2018: 4, 6 or 8 power moments in 32-bit \
                 targets, two passes"
            }
            Method::LinkedList => {
                "a budgeted per-pixel linked list, as Bevy ships it: fragments kept first come, \
                 first served until the budget's nodes are spent, the rest dropped; the nearest 8 \
                 of a pixel sorted"
            }
        }
    }

    /// Whether an application renders the method with dhoit's `Oit` types, in its own encoder
    /// ([`crate::gpu::Oit`]): the methods a renderer ships, which the viewer example offers.
    /// The CPU's allocations (the optimum, the greedy ones) are ceilings to measure against.
    pub fn in_application(self) -> bool {
        !matches!(
            self,
            Method::Optimal | Method::OptimalPooled | Method::GreedyPaper | Method::GreedyIncrease
        )
    }

    /// Whether the method's GPU frame keeps to its budget's bytes, so that it is compared with
    /// the others at equal memory: `versus`'s methods, and those the GPU bench streams along an
    /// orbit. The application's methods but MLAB, whose GPU frame blends from the A-buffer's
    /// fragments, with the A-buffer's memory.
    pub fn at_equal_bytes(self) -> bool {
        self.in_application() && self != Method::Mlab
    }

    /// Whether the GPU bench times the method's frames: those at equal bytes, and the optimal
    /// allocation (its k uploaded: the ceiling of the k-buffers' passes; the greedy ones and
    /// the pooled optimum take the same passes, or none).
    pub fn gpu_timed(self) -> bool {
        self.at_equal_bytes() || self == Method::Optimal
    }

    /// The methods `keep` selects, in the registry's order ([`Method::ALL`]).
    pub fn those(keep: impl Fn(Method) -> bool) -> Vec<Method> {
        Method::ALL.into_iter().filter(|&m| keep(m)).collect()
    }

    /// The most memory the method's CPU frame adds to its fragment lists, as bytes a fragment
    /// and a pixel: its allocation's state, the image and its encoding. Fitted to the peak
    /// resident size of `dhoit render` on `cad` at 4096x4096 (1.3 fragments a pixel) and
    /// `particles` at 2048x2048 (9.7), less the lists' 28 bytes a fragment and 4 a pixel, and
    /// rounded up (bounds, not measurements: where the rasterizer's peak hid the frame's, the
    /// larger share is assumed): the sorted copies the composite takes, the image and its
    /// encoding; the features and importance of DKB; the error curves and the allocation's
    /// hulls or heaps of the optimal and the greedy ones.
    pub fn frame_bytes(self) -> (u64, u64) {
        match self {
            Method::Abuffer
            | Method::Fkb
            | Method::Vkb
            | Method::Mlab
            | Method::Wboit
            | Method::Mboit
            | Method::LinkedList => (28, 40),
            Method::Dkb => (24, 120),
            Method::Optimal
            | Method::OptimalPooled
            | Method::GreedyPaper
            | Method::GreedyIncrease => (70, 40),
        }
    }

    /// Whether the method is a k-buffer (FKB, VKB, DKB and the allocations the CPU makes): it
    /// renders exactly, with the A-buffer's memory, where its budget holds every fragment
    /// ([`crate::frame::Renderer::allocate`]).
    pub fn is_kbuffer(self) -> bool {
        !matches!(
            self,
            Method::Abuffer | Method::Mlab | Method::Wboit | Method::Mboit | Method::LinkedList
        )
    }

    /// The buffers the method's GPU pipeline creates.
    pub fn layout(self) -> Layout {
        match self {
            Method::Abuffer => budget::ABUFFER,
            Method::Fkb => budget::FKB,
            Method::Vkb => budget::VKB,
            Method::Dkb => budget::DKB,
            Method::Optimal | Method::GreedyPaper | Method::GreedyIncrease => budget::OPT,
            // DKB's own layout: at equal bytes the optimum gets DKB's F.
            Method::OptimalPooled => budget::DKB,
            Method::Mlab => budget::MLAB,
            Method::Wboit => budget::WBOIT,
            Method::Mboit => budget::MBOIT,
            Method::LinkedList => budget::LINKED_LIST,
        }
    }
}

/// Every method with what it is, as `dhoit --help` lists them: "abuffer (exact reference),
/// fkb (fixed k-buffer), ...".
pub fn help() -> String {
    let items: Vec<String> = Method::ALL
        .iter()
        .map(|m| format!("{m} ({})", m.summary()))
        .collect();
    items.join(", ")
}

impl std::str::FromStr for Method {
    type Err = Error;
    fn from_str(s: &str) -> Result<Method> {
        Method::parse(s)
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The most bytes a k-buffer method's frame of occupancy `occ` can allocate at F: its fixed
/// bytes, `min(F, n)` slots (the slots an allocation hands out at most; the GPU sizes its slots
/// buffer from what it hands out) and the pooled tails its pixels may keep
/// ([`Layout::reserved_bytes`]), FKB and MLAB their uniform k for every pixel.
pub fn reserved_bytes(
    method: Method,
    layout: &Layout,
    pixels: u64,
    f: u64,
    occ: &Occupancy,
) -> u64 {
    match method {
        Method::Fkb | Method::Mlab => layout.allocated_bytes(pixels, f / pixels.max(1) * pixels),
        _ => layout.reserved_bytes(pixels, f, occ),
    }
}

/// Whether the exact A-buffer of a frame of occupancy `occ` needs no more bytes than a
/// k-buffer method reserves for it at F ([`reserved_bytes`]): then the A-buffer is both better
/// and no dearer, and [`budget::Decision::exact_when_cheaper`] renders it instead (on the CPU,
/// and on the GPU from its own count).
pub fn exact_is_no_dearer(
    method: Method,
    layout: &Layout,
    pixels: u64,
    f: u64,
    occ: &Occupancy,
) -> bool {
    reserved_bytes(method, layout, pixels, f, occ)
        >= budget::ABUFFER.allocated_bytes(pixels, occ.fragments)
}
