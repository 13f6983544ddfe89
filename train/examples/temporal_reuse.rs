//! What DKB loses where a frame allocates with the importance the network gave the frame
//! before (the network run every other frame), measured on the CPU twin: for each built-in
//! family's held-out scene (seed 1, every surface at opacity 0.33), views of an orbit of
//! `views` frames (120: a slow camera, 3 degrees a frame; 30: a fast one, 12 degrees), each
//! frame's allocation from its own importance and from the frame before's, against the
//! per-pixel optimal allocation, at `score`'s ten budgets.
//!
//! `cargo run --release -p dhoit-train --example temporal_reuse [VIEWS...]` (default 120 30).
//! Where a pixel had no importance the frame before (newly covered, or forced then) and the
//! network would run on it now, it takes the mean of the frame before's requests, as the GPU
//! gives a pixel its frame before did not mark.

use dhoit_runtime::mlp::Mlp;
use dhoit_runtime::scene::{Camera, procedural::BUILTIN};
use dhoit_runtime::{alloc, importance, raster};
use dhoit_train::dataset::{self, Level};
use dhoit_train::score::geomean;
use rayon::prelude::*;

const SIZE: (u32, u32) = (320, 240);
/// Views of each orbit scored (their frame before is the view before).
const SCORED: usize = 4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let orbits: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse())
        .collect::<Result<_, _>>()?;
    let orbits = if orbits.is_empty() {
        vec![120, 30]
    } else {
        orbits
    };
    let m = Mlp::load(std::path::Path::new("data/weights.safetensors"))?;
    let levels: Vec<Level> = dhoit_train::cli::SCORE_BUDGETS
        .split(',')
        .map(|s| s.parse())
        .collect::<Result<_, _>>()?;
    println!(
        "| orbit | family | frames | DKB/optimal, own importance | the frame before's | ratio |"
    );
    println!("|---|---|---:|---:|---:|---:|");
    for &views in &orbits {
        let mut own_all = Vec::new();
        let mut prev_all = Vec::new();
        let only = std::env::var("TEMPORAL_REUSE_FAMILIES").unwrap_or_default();
        for (family, _) in BUILTIN.iter() {
            if !only.is_empty() && !only.split(',').any(|f| f == *family) {
                continue;
            }
            let names = [format!("{family}:1")];
            let sc = &dataset::load_scenes(&names, Some(0.33))?[0];
            let pairs: Vec<(f64, f64)> = (0..SCORED)
                .into_par_iter()
                .map(|i| {
                    let view = 1 + i * views / SCORED;
                    frame_pair(&m, sc, view, views, &levels)
                })
                .collect::<Result<Vec<_>, _>>()?
                .into_iter()
                .flatten()
                .collect();
            let own = geomean(pairs.iter().map(|p| p.0));
            let prev = geomean(pairs.iter().map(|p| p.1));
            println!(
                "| {views} | {family} | {} | {own:.3} | {prev:.3} | {:.3} |",
                pairs.len(),
                prev / own
            );
            own_all.extend(pairs.iter().map(|p| p.0));
            prev_all.extend(pairs.iter().map(|p| p.1));
        }
        let (own, prev) = (geomean(own_all.iter().copied()), geomean(prev_all));
        println!(
            "| {views} | **every family** | {} | {own:.3} | {prev:.3} | {:.3} |",
            own_all.len(),
            prev / own
        );
    }
    Ok(())
}

/// Frame `view`'s (DKB/optimal own, DKB/optimal from the frame before's importance) at every
/// level that truncates it.
fn frame_pair(
    m: &Mlp,
    sc: &dhoit_runtime::scene::Scene,
    view: usize,
    views: usize,
    levels: &[Level],
) -> Result<Vec<(f64, f64)>, dhoit_runtime::Error> {
    let frame = |v: usize| raster::rasterize(sc, &Camera::orbit(sc, v, views, SIZE), SIZE);
    // TEMPORAL_REUSE_SAME=1: the frame "before" is the frame itself (the check: ratio 1).
    let same = std::env::var_os("TEMPORAL_REUSE_SAME").is_some();
    let (before, now) = (frame(if same { view } else { view - 1 })?, frame(view)?);
    let curves = alloc::error_curves(&now, [1.0; 3]);
    let (counts, counts_before) = (now.counts(), before.counts());
    let (pixels, total) = (now.pixel_count() as u64, now.fragment_count() as u64);
    let total_before = before.fragment_count() as u64;
    let mut out = Vec::new();
    for level in levels {
        let f = level.fragments(pixels, total).max(1);
        if f >= total {
            continue;
        }
        let (_, optimal) = alloc::optimal(&curves, f);
        let floor = |e: f64| e.max(dataset::error_floor(pixels));
        let (feats, pairs) = importance::features_and_pairs(&now, f);
        let own = m.allocate(&feats, &counts, &pairs, f);
        // The frame before's importance at its own F for the same budget.
        let f_before = level.fragments(pixels, total_before).max(1);
        let (feats_b, pairs_b) = importance::features_and_pairs(&before, f_before);
        let imp_b = m.dkb_importance(&feats_b, &counts_before, &pairs_b, f_before);
        let requests: Vec<f32> = imp_b.iter().map(|i| i.abs()).filter(|&i| i > 0.0).collect();
        let mean = requests.iter().sum::<f32>() / requests.len().max(1) as f32;
        // Where the network would run now: what the frame before gave, else the mean.
        let imp_now = m.dkb_importance(&feats, &counts, &pairs, f);
        let reused: Vec<f32> = imp_now
            .iter()
            .zip(&imp_b)
            .zip(&pairs)
            .map(|((&i_now, &i_b), &pair)| {
                if i_now.abs() == 0.0 {
                    return i_now;
                }
                let v = if i_b.abs() > 0.0 { i_b.abs() } else { mean };
                alloc::mark_pair(v, pair)
            })
            .collect();
        let prev = alloc::allocate(&reused, &counts, m.target, f);
        out.push((
            floor(curves.total(&own)) / floor(optimal.total),
            floor(curves.total(&prev)) / floor(optimal.total),
        ));
    }
    Ok(out)
}
