//! One frame on the CPU: fragment lists in, a method's per-pixel k and image out, with the
//! budget and memory figures every method reports.

use crate::budget::{self, Budget, Layout};
use crate::composite::{self, Image, Method as Composite};
use crate::error::{Error, Result};
use crate::raster::FragmentLists;
use std::time::Instant;

/// Rendering methods.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Method {
    /// Exact A-buffer: every fragment sorted and blended (the reference image).
    Abuffer,
    /// Fixed k-buffer: one k for every pixel.
    Fkb,
    /// Multi-layer alpha blending at the same bytes per pixel.
    Mlab,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Abuffer, Method::Fkb, Method::Mlab];

    pub fn name(self) -> &'static str {
        match self {
            Method::Abuffer => "abuffer",
            Method::Fkb => "fkb",
            Method::Mlab => "mlab",
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

    pub fn layout(self) -> Layout {
        match self {
            Method::Abuffer => budget::ABUFFER,
            Method::Fkb => budget::FKB,
            Method::Mlab => budget::MLAB,
        }
    }
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
    /// Milliseconds spent on allocation and on compositing.
    pub allocation_ms: f64,
    pub composite_ms: f64,
}

/// Renders `fl` with `method` under `budget` over the background.
pub fn render(
    fl: &FragmentLists,
    method: Method,
    budget: Budget,
    background: [f32; 3],
) -> Result<Frame> {
    let pixels = fl.pixel_count() as u64;
    let counts = fl.counts();
    let total = fl.fragment_count() as u64;
    let layout = method.layout();
    let t0 = Instant::now();
    let (budget_bytes, budget_fragments, k) = match method {
        Method::Abuffer => (layout.allocated_bytes(pixels, total), total, counts.clone()),
        Method::Fkb | Method::Mlab => {
            let (m, f) = budget.resolve(&layout, pixels)?;
            let per = f / pixels.max(1);
            if per == 0 {
                let need = layout.allocated_bytes(pixels, pixels);
                return Err(Error::Budget(
                    budget.to_string(),
                    format!(
                        "{} needs one slot for every pixel: at least {} at {}x{}",
                        method.name(),
                        budget::format_bytes(need),
                        fl.width,
                        fl.height
                    ),
                ));
            }
            (m, f, vec![per.min(u32::MAX as u64) as u32; pixels as usize])
        }
    };
    let allocation_ms = t0.elapsed().as_secs_f64() * 1e3;
    let slots: u64 = k.iter().map(|&x| x as u64).sum();
    let captured: u64 = k.iter().zip(&counts).map(|(&a, &b)| a.min(b) as u64).sum();
    let t1 = Instant::now();
    let image = match method {
        Method::Abuffer => composite::composite(fl, Composite::Exact, background),
        Method::Fkb => composite::composite(fl, Composite::Hybrid(&k), background),
        Method::Mlab => composite::composite(
            fl,
            Composite::Mlab(k.first().copied().unwrap_or(1) as usize),
            background,
        ),
    };
    let composite_ms = t1.elapsed().as_secs_f64() * 1e3;
    Ok(Frame {
        method,
        image,
        allocated_bytes: layout.allocated_bytes(pixels, slots),
        k,
        budget_bytes,
        budget_fragments,
        fragments_total: total,
        fragments_captured: captured,
        allocation_ms,
        composite_ms,
    })
}
