//! One frame on the CPU: fragment lists in, a method's per-pixel k and image out, with the
//! budget and memory figures every method reports.

use crate::alloc::{self, ErrorCurves, GreedyKey, OptimalReport};
use crate::budget::{self, Budget, FragmentBudget, Layout, Occupancy};
use crate::composite::{self, Image, MboitParams, Method as Composite, WboitParams};
use crate::error::{Error, Result};
use crate::fragment::FragmentLists;
use crate::importance::{self, VkbParams};
pub use crate::method::{Method, exact_is_no_dearer, reserved_bytes};
use crate::mlp::Mlp;
use crate::plan::{self, Counted, PlanBudget};
use std::sync::OnceLock;
use std::time::Instant;

/// What `budget` comes to for `method` on the frame `fl`: a k-buffer's as [`plan::counted`]
/// decides it (whether it renders the exact A-buffer included); the A-buffer's bytes and every
/// fragment; the blended methods' targets and no slot; the list's nodes. Or the budget's
/// refusal.
fn reserved(
    fl: &FragmentLists,
    method: Method,
    budget: Budget,
    layout: &budget::Layout,
    occ: &Occupancy,
    moments: u32,
) -> Result<Counted> {
    let pixels = fl.pixel_count() as u64;
    let total = fl.fragment_count() as u64;
    if method.is_kbuffer() {
        let b = PlanBudget::of(budget, pixels, total)?;
        return plan::counted(method, layout, b, pixels, occ, fl.words());
    }
    let (bytes, f) = match (method, budget) {
        (Method::Abuffer, _) => (budget::abuffer_bytes(pixels, total, fl.tinted()), total),
        // Fixed memory whatever the budget: its accumulation targets, no slot. A byte
        // budget is a cap for them as for every method: targets above it do not run.
        (Method::Wboit | Method::Mboit, b) => {
            // Their transmittance targets where the frame's glass is tinted.
            let need = layout.fixed_bytes(pixels) + tint_target_bytes(method, fl, pixels);
            match b {
                Budget::Bytes(m) if need > m => {
                    return Err(Error::Budget(
                        budget::format_bytes(m),
                        format!(
                            "{} needs {} for its targets on {} pixels ({} B a pixel{}), \
                             whatever the frame's fragments",
                            method.name(),
                            budget::format_bytes(need),
                            pixels,
                            layout.per_pixel_bytes(),
                            moments_note(method, moments, pixels)
                        ),
                    ));
                }
                _ => (need, 0),
            }
        }
        // The list's nodes take what their tints leave of M.
        (Method::LinkedList, Budget::Bytes(m)) if fl.tinted() => (
            m,
            layout.tinted_fragment_budget(m, pixels, occ, fl.words())?,
        ),
        // F fixed by slots or a share (MLAB's rows, the list's nodes): the bytes it reserves,
        // with a tint a node where the frame's glass is tinted.
        _ => {
            let (bytes, f) = budget.resolve_counted(layout, pixels, occ)?;
            let tints = (method == Method::LinkedList && fl.tinted()) as u64;
            (bytes + tints * budget::TINT_BYTES * f, f)
        }
    };
    Ok(Counted {
        bytes,
        f,
        holds_all: false,
        no_dearer: false,
    })
}

/// DKB without a network.
pub(crate) fn no_weights() -> Error {
    Error::Invalid("dkb needs network weights (--weights FILE)".into())
}

/// What `method`'s own options must be, whatever the frame: DKB's weights, the list's sorted
/// mode, MBOIT's moments, WBOIT's weight.
fn check_method_options(method: Method, opts: &Options) -> Result<()> {
    match method {
        Method::Dkb if opts.weights.is_none() => Err(no_weights()),
        Method::LinkedList => composite::check_list_sorted(opts.list_sorted),
        Method::Mboit => composite::MboitParams::with_moments(opts.mboit.moments).map(|_| ()),
        Method::Wboit => opts.wboit.check(),
        _ => Ok(()),
    }
}

/// FKB and MLAB give every pixel the same k (slots, rows): F must hold one for every pixel.
fn check_slot_per_pixel(method: Method, given: Budget, f: u64, size: (u32, u32)) -> Result<()> {
    let (w, h) = size;
    let pixels = w as u64 * h as u64;
    if matches!(method, Method::Fkb | Method::Mlab) && f < pixels {
        return Err(Error::Budget(
            given.to_string(),
            format!(
                "{method} needs one slot for every pixel: at least {} at {w}x{h}",
                budget::format_bytes(method.layout().allocated_bytes(pixels, pixels)),
            ),
        ));
    }
    Ok(())
}

/// Refuses, before any frame is rendered, a budget that cannot hold `method` at `size` (width,
/// height): its fixed cost, and a slot for every pixel where the method needs one. A budget in
/// bytes or in slots per pixel depends on the resolution alone; a share of the frame's
/// fragments (and the exact A-buffer) passes here and is checked with each frame.
pub fn check_budget(given: Budget, method: Method, size: (u32, u32)) -> Result<()> {
    let (w, h) = size;
    // The A-buffer, WBOIT and MBOIT take no budget: exact memory, fixed memory.
    if matches!(method, Method::Abuffer | Method::Wboit | Method::Mboit)
        || matches!(given, Budget::Share(_))
    {
        return Ok(());
    }
    let (_, f) = given.resolve(&method.layout(), w as u64 * h as u64, 0)?;
    check_slot_per_pixel(method, given, f, size)
}

/// What rendering one frame with one method produced.
#[derive(Clone, Debug)]
pub struct Frame {
    pub method: Method,
    pub image: Image,
    /// The method's per-pixel k (slots per pixel; MLAB: rows).
    pub k: Vec<u32>,
    /// The budget M in bytes.
    pub budget_bytes: u64,
    /// F(M): fragment slots the budget allows.
    pub budget_fragments: u64,
    /// Bytes the method's pipeline allocates for this frame.
    pub allocated_bytes: u64,
    /// Fragments in the frame.
    pub fragments_total: u64,
    /// Fragments composited exactly (kept in a slot).
    pub fragments_captured: u64,
    /// Milliseconds spent on allocation (features, importance, k) and on compositing.
    pub allocation_ms: f64,
    pub composite_ms: f64,
    /// Totals of the optimal allocation and the greedies (optimal method only).
    pub optimal: Option<OptimalReport>,
    /// Whether the k-buffer method rendered the exact A-buffer ([`Allocation::exact`]).
    pub exact: bool,
}

/// A method's k for one frame and the budget behind it, before compositing.
#[derive(Clone, Debug)]
pub struct Allocation {
    pub method: Method,
    /// Slots per pixel (MLAB: rows); empty when the GPU allocates ([`Renderer::allocate_for_gpu`]).
    pub k: Vec<u32>,
    /// The budget M in bytes.
    pub budget_bytes: u64,
    /// F(M).
    pub budget_fragments: u64,
    /// F as a GPU frame takes it: a share at equal F stays a share (the device resolves it from
    /// its own count), every other budget F slots. Decided here, with [`Equal`], once.
    pub fragment_budget: FragmentBudget,
    pub allocation_ms: f64,
    /// The optimal allocation's report (optimal method only).
    pub optimal: Option<OptimalReport>,
    /// Whether the k-buffer method renders the exact A-buffer (k = n) with its memory: where
    /// the budget holds every fragment (a budget is a cap, not a quantity to spend), or where
    /// the A-buffer needs no more bytes than the method would ([`budget::Decision::exact_when_cheaper`]).
    pub exact: bool,
}

/// What the methods of one frame share, so that their errors compare.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Equal {
    /// The same F for every method: slots per pixel or a share of the fragments fix F, and each
    /// method's bytes follow from its layout (a byte budget fixes M instead).
    #[default]
    Slots,
    /// The same bytes M for every method, each method's F following from its own layout (the
    /// paper's protocol). A budget in slots or a share sets M to what DKB's layout (the largest
    /// per-pixel cost, [`budget::DKB`], with its network's weights: [`Options::layout`]) needs
    /// for that F, so every per-pixel-k method fits and the leaner ones get more slots than
    /// DKB for the same memory.
    Bytes,
}

impl std::str::FromStr for Equal {
    type Err = Error;
    fn from_str(s: &str) -> Result<Equal> {
        Equal::parse(s)
    }
}

impl Equal {
    /// `slots` or `bytes`.
    pub fn parse(s: &str) -> Result<Equal> {
        match s {
            "slots" | "f" => Ok(Equal::Slots),
            "bytes" | "m" => Ok(Equal::Bytes),
            _ => Err(Error::Invalid(format!(
                "unknown comparison '{s}': expected slots (the same F for every method) or bytes (the same memory M)"
            ))),
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Equal::Slots => "equal F",
            Equal::Bytes => "equal bytes",
        }
    }
}

/// Settings shared by every method of a frame.
#[derive(Clone, Copy, Debug)]
pub struct Options<'a> {
    pub budget: Budget,
    /// Equal F or equal bytes across methods.
    pub equal: Equal,
    pub background: [f32; 3],
    /// Network weights, needed by DKB.
    pub weights: Option<&'a Mlp>,
    pub vkb: VkbParams,
    /// MBOIT's moment bias and overestimation (the paper's defaults).
    pub mboit: MboitParams,
    /// WBOIT's weight function (eq. 10, of the window depth, by default) and, for those of the
    /// view-space distance, the camera's planes ([`composite::WboitParams::for_camera`]).
    pub wboit: WboitParams,
    /// The linked list's fragments a pixel sorted at resolve, 1 to
    /// [`composite::LIST_MAX_SORTED`] ([`composite::LIST_SORTED`], Bevy's 8, by default).
    pub list_sorted: u32,
    /// How a k-buffer method's budget is decided: the exact A-buffer where it is no dearer
    /// (on by default: a memory-bounded method never costs more than the exact answer), and
    /// DKB's record batches. The GPU frame takes the same ([`crate::gpu::FrameOptions`]).
    pub decision: budget::Decision,
}

impl Options<'_> {
    pub fn new(budget: Budget, background: [f32; 3]) -> Options<'static> {
        Options {
            budget,
            equal: Equal::Slots,
            background,
            weights: None,
            vkb: VkbParams::default(),
            mboit: MboitParams::default(),
            wboit: WboitParams::default(),
            list_sorted: composite::LIST_SORTED,
            decision: budget::Decision::default(),
        }
    }

    /// These options with the k-buffer methods rendering their approximation even where the
    /// exact A-buffer would need fewer bytes ([`budget::Decision::exact_when_cheaper`] off).
    pub fn always_approximate(self) -> Self {
        Options {
            decision: self.decision.always_approximate(),
            ..self
        }
    }

    /// The buffers `method`'s GPU pipeline creates: DKB's with these weights' own bytes (a
    /// smaller network, or f16, costs less), MBOIT's for its number of moments, else
    /// [`Method::layout`].
    pub fn layout(&self, method: Method) -> Layout {
        match (method, self.weights) {
            (Method::Dkb | Method::OptimalPooled, Some(m)) => self.decision.dkb_layout(m),
            (Method::Mboit, _) => budget::mboit(self.mboit.moments),
            _ => method.layout(),
        }
    }
}

/// What a blended method's refused byte budget adds to its message: MBOIT's power moments,
/// and what the fewest would need where more were asked for (nothing for WBOIT).
fn moments_note(method: Method, moments: u32, pixels: u64) -> String {
    match method {
        Method::Mboit if moments > 4 => format!(
            " at {moments} power moments; 4 need {}",
            budget::format_bytes(budget::mboit(4).fixed_bytes(pixels))
        ),
        Method::Mboit => " at 4 power moments, the fewest".into(),
        _ => String::new(),
    }
}

/// Renders one frame's fragment lists with any method, computing the error curves once.
///
/// ```
/// use dhoit_runtime::budget::Budget;
/// use dhoit_runtime::frame::{Method, Options, Renderer};
/// use dhoit_runtime::{raster, scene};
///
/// let s = scene::load("plates", scene::Opacity::default())?;
/// let cam = scene::Camera::orbit(&s, 0, scene::DEFAULT_VIEWS, (96, 72));
/// let fragments = raster::rasterize(&s, &cam, (96, 72))?;
/// // The methods' own approximations at one fragment slot a pixel.
/// let r = Renderer::new(&fragments, Options::new(Budget::parse("1fpp")?, [1.0; 3]).always_approximate());
/// let exact = r.render(Method::Abuffer)?;
/// let (fkb, optimal) = (r.render(Method::Fkb)?, r.render(Method::Optimal)?);
/// // The optimal allocation of the same F is never worse than one k for every pixel.
/// assert!(optimal.image.mse(&exact.image) <= fkb.image.mse(&exact.image));
/// assert_eq!(optimal.budget_fragments, 96 * 72);
/// # Ok::<(), dhoit_runtime::Error>(())
/// ```
pub struct Renderer<'a> {
    pub fragments: &'a FragmentLists,
    pub options: Options<'a>,
    curves: OnceLock<ErrorCurves>,
}

impl<'a> Renderer<'a> {
    pub fn new(fragments: &'a FragmentLists, options: Options<'a>) -> Self {
        Renderer {
            fragments,
            options,
            curves: OnceLock::new(),
        }
    }

    /// Error curves of every pixel against the exact image (computed on first use).
    pub fn curves(&self) -> &ErrorCurves {
        self.curves
            .get_or_init(|| alloc::error_curves(self.fragments, self.options.background))
    }

    /// The budget every method of this frame gets, after [`Equal`]: at equal bytes, a budget in
    /// slots or a share becomes the bytes DKB spends on it: what its layout reserves (with its
    /// tints where the frame's glass is tinted), or where that is no less than the exact
    /// A-buffer's bytes and [`budget::Decision::exact_when_cheaper`] renders the A-buffer instead, the
    /// A-buffer's (no method gets more memory than DKB spends).
    pub fn budget(&self) -> Result<Budget> {
        let opts = &self.options;
        match (opts.equal, opts.budget) {
            (Equal::Bytes, b @ (Budget::SlotsPerPixel(_) | Budget::Share(_))) => {
                let fl = self.fragments;
                let (pixels, n) = (fl.pixel_count() as u64, fl.fragment_count() as u64);
                let dkb = opts.layout(Method::Dkb);
                let b = PlanBudget::of(b, pixels, n)?;
                let occ = Occupancy::of(&fl.counts());
                let bytes = plan::counted(Method::Dkb, &dkb, b, pixels, &occ, fl.words())?.bytes;
                let exact = budget::abuffer_bytes(pixels, n, fl.tinted());
                Ok(Budget::Bytes(match opts.decision.exact_when_cheaper {
                    true => bytes.min(exact),
                    false => bytes,
                }))
            }
            (_, b) => Ok(b),
        }
    }

    /// The method's k on the CPU, with the budget figures, before compositing.
    pub fn allocate(&self, method: Method) -> Result<Allocation> {
        self.allocate_with(method, true)
    }

    /// What the GPU needs from the CPU to render `method` (see `gpu::Slots::for_method`): the
    /// budget and F, and k only where the GPU cannot compute it itself (VKB and DKB allocate
    /// on the device: their k is left empty, no CPU time spent on it).
    pub fn allocate_for_gpu(&self, method: Method) -> Result<Allocation> {
        self.allocate_with(method, !matches!(method, Method::Vkb | Method::Dkb))
    }

    fn allocate_with(&self, method: Method, cpu_k: bool) -> Result<Allocation> {
        let fl = self.fragments;
        let opts = &self.options;
        let pixels = fl.pixel_count() as u64;
        let counts = fl.counts();
        let occ = Occupancy::of(&counts);
        let layout = opts.layout(method);
        let t0 = Instant::now();
        // Refused whatever the frame: even one the A-buffer renders exactly.
        check_method_options(method, opts)?;
        let budget = self.budget()?;
        let counted = reserved(fl, method, budget, &layout, &occ, opts.mboit.moments)?;
        let (budget_bytes, f) = (counted.bytes, counted.f);
        // Exact where the budget holds every fragment, and (unless told otherwise) where the
        // A-buffer needs no more bytes than the method reserves for this budget: then the
        // exact answer is both better and no dearer.
        let exact = counted.exact(opts.decision.exact_when_cheaper);
        let mut optimal = None;
        let k = match method {
            Method::Abuffer => counts,
            _ if exact => counts,
            Method::Wboit | Method::Mboit => vec![0; pixels as usize],
            // The fragments the list kept, by pixel.
            Method::LinkedList => fl.retain(&composite::linked_list_kept(fl, f)).counts(),
            Method::Fkb | Method::Mlab => {
                check_slot_per_pixel(method, opts.budget, f, fl.size())?;
                alloc::fixed(pixels as usize, f)
            }
            Method::Vkb | Method::Dkb if !cpu_k => Vec::new(),
            // Their tails pooled: every pixel is a pair (alloc::allocate_pooled).
            Method::Vkb => {
                let imp = importance::vkb_importance(fl, &opts.vkb);
                alloc::allocate_pooled(&imp, &counts, alloc::Target::RelativeK, f)
            }
            Method::Dkb => {
                let mlp = opts.weights.ok_or_else(no_weights)?;
                let (feats, _) = importance::features_and_pairs(fl, f);
                mlp.allocate_pooled(&feats, &counts, f)
            }
            Method::Optimal => {
                let (k, rep) = alloc::optimal(self.curves(), f);
                optimal = Some(rep);
                k
            }
            Method::OptimalPooled => {
                let (k, rep) = alloc::optimal(&self.curves().pooled(), f);
                optimal = Some(rep);
                k
            }
            Method::GreedyPaper => alloc::greedy(self.curves(), f, GreedyKey::NewError),
            Method::GreedyIncrease => alloc::greedy(self.curves(), f, GreedyKey::Increase),
        };
        // At equal bytes a share has become bytes (Renderer::budget).
        let fragment_budget = match budget {
            Budget::Share(ppm) => FragmentBudget::Share(ppm),
            _ => FragmentBudget::Slots(f),
        };
        Ok(Allocation {
            method,
            k,
            budget_bytes,
            budget_fragments: f,
            fragment_budget,
            allocation_ms: t0.elapsed().as_secs_f64() * 1e3,
            optimal,
            exact,
        })
    }

    /// Composites an allocation of this frame on the CPU.
    pub fn composite(&self, a: Allocation) -> Frame {
        let fl = self.fragments;
        let pixels = fl.pixel_count() as u64;
        let counts = fl.counts();
        let method = a.method;
        // A k-buffer whose tails share its slots' pool keeps all of a pixel's fragments where
        // a tail would hold no more (shared::stored_k): the k it stores.
        let pooled = !a.exact && self.options.layout(method).tail_bytes > 0;
        let k = match pooled {
            true => crate::shared::stored(&a.k, &counts),
            false => a.k,
        };
        let slots: u64 = k.iter().map(|&x| x as u64).sum();
        let captured: u64 = k.iter().zip(&counts).map(|(&a, &b)| a.min(b) as u64).sum();
        let t1 = Instant::now();
        let bg = self.options.background;
        let image = match method {
            Method::Abuffer => composite::composite(fl, Composite::Exact, bg),
            _ if a.exact => composite::composite(fl, Composite::Exact, bg),
            Method::Mlab => composite::composite(fl, Composite::Mlab(k[0] as usize), bg),
            Method::Wboit => composite::composite(fl, Composite::Wboit(self.options.wboit), bg),
            Method::Mboit => composite::composite(fl, Composite::Mboit(self.options.mboit), bg),
            Method::LinkedList => {
                let kept = fl.retain(&composite::linked_list_kept(fl, a.budget_fragments));
                let sorted = vec![self.options.list_sorted; pixels as usize];
                composite::composite(&kept, Composite::Hybrid(&sorted), bg)
            }
            _ => composite::composite(fl, Composite::Hybrid(&k), bg),
        };
        let composite_ms = t1.elapsed().as_secs_f64() * 1e3;
        // FKB and MLAB allocate their k for every pixel; the others exactly sum k; a frame
        // whose budget holds every fragment, what the A-buffer does (with each fragment's tint
        // where the frame's glass is tinted).
        let allocated_bytes = match method {
            _ if a.exact || method == Method::Abuffer => {
                budget::abuffer_bytes(pixels, slots, fl.tinted())
            }
            Method::Wboit | Method::Mboit => {
                self.options.layout(method).allocated_bytes(pixels, 0)
                    + tint_target_bytes(method, fl, pixels)
            }
            // Its whole pool of F nodes, however many arrived, with a tint a node where the
            // frame's glass is tinted.
            Method::LinkedList => {
                method.layout().allocated_bytes(pixels, a.budget_fragments)
                    + fl.tinted() as u64 * budget::TINT_BYTES * a.budget_fragments
            }
            Method::Mlab => method
                .layout()
                .allocated_bytes(pixels, k[0] as u64 * pixels),
            Method::Fkb => {
                let layout = method.layout();
                let bytes = layout.allocated_bytes(pixels, k[0] as u64 * pixels);
                layout.with_tints(bytes, pixels, fl.words())
            }
            // Its slots, and the tails it keeps in their pool (none where they are per pixel);
            // a pool made before the allocation for state it holds first (DKB), the size it
            // is made at for the frame's budget and occupancy.
            _ => {
                let layout = self.options.layout(method);
                let bytes = if layout.pool_state.is_some() {
                    let occ = Occupancy::of(&counts);
                    // A byte budget that holds DKB's records only in batches reserves a pool
                    // of a batch of them.
                    let layout = match self.budget() {
                        Ok(Budget::Bytes(m)) => {
                            let m = layout.tinted_budget(m, pixels, fl.words());
                            layout.for_bytes(m, pixels, &occ)
                        }
                        _ => layout,
                    };
                    layout.reserved_bytes(pixels, a.budget_fragments, &occ)
                } else {
                    layout.allocated_with_tails(pixels, slots, budget::tails_kept(&k, &counts))
                };
                layout.with_tints(bytes, pixels, fl.words())
            }
        };
        Frame {
            method,
            image,
            allocated_bytes,
            k,
            budget_bytes: a.budget_bytes,
            budget_fragments: a.budget_fragments,
            fragments_total: fl.fragment_count() as u64,
            fragments_captured: captured,
            allocation_ms: a.allocation_ms,
            composite_ms,
            optimal: a.optimal,
            exact: a.exact,
        }
    }

    pub fn render(&self, method: Method) -> Result<Frame> {
        Ok(self.composite(self.allocate(method)?))
    }
}

/// The bytes WBOIT's or MBOIT's transmittance target adds where the frame's glass is tinted
/// ([`budget::WBOIT_TINT_BYTES`], [`budget::MBOIT_TINT_BYTES`]; 0 for any other frame).
fn tint_target_bytes(method: Method, fl: &FragmentLists, pixels: u64) -> u64 {
    let bytes = match method {
        Method::Wboit => budget::WBOIT_TINT_BYTES,
        Method::Mboit => budget::MBOIT_TINT_BYTES,
        _ => 0,
    };
    fl.tinted() as u64 * bytes * pixels
}

/// Refuses a frame whose methods' CPU work ([`Method::frame_bytes`], the most of them) would
/// not fit in the memory still available beside its fragment lists
/// ([`crate::raster::available_memory`]), with the numbers: before any of them starts, where
/// the allocation would fail or the system stop the process without a word.
pub fn check_memory(methods: &[Method], fl: &FragmentLists) -> Result<()> {
    let (n, p) = (fl.fragment_count() as u64, fl.pixel_count() as u64);
    let need = |m: Method| {
        let (a, b) = m.frame_bytes();
        a.saturating_mul(n).saturating_add(b.saturating_mul(p))
    };
    let Some(&m) = methods.iter().max_by_key(|&&m| need(m)) else {
        return Ok(());
    };
    let (a, b) = m.frame_bytes();
    crate::raster::check_fits(fl.size(), need(m), |bytes| {
        format!(
            "{m} needs about {bytes} beside the view's {n} fragments ({a} a fragment, {b} a pixel)"
        )
    })
}

/// Renders `fl` with one method (see [`Renderer`] to share work between methods).
pub fn render(fl: &FragmentLists, method: Method, options: Options) -> Result<Frame> {
    Renderer::new(fl, options).render(method)
}
