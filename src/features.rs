//! `dhoit features`: the 12 network features of one view's covered pixels, for `predict`.

use crate::args::{ViewArgs, load_scene, rasterize_view};
use anyhow::{Result, bail};
use clap::Args;
use dhoit_runtime::budget::Budget;
use dhoit_runtime::tensors::{self, Entry};
use std::path::PathBuf;

#[derive(Args)]
pub struct FeaturesArgs {
    /// Built-in scene name (optionally `name:seed`) or path to a .gltf/.glb file.
    #[arg(long, default_value = "particles")]
    scene: String,
    #[arg(long, default_value_t = 0)]
    view: usize,
    #[command(flatten)]
    common: ViewArgs,
    /// Budget the features describe (F / sum n is a feature), for the DKB layout.
    #[arg(long, default_value = "2fpp", allow_hyphen_values = true)]
    budget: Budget,
    /// Keep at most this many covered pixels, evenly spaced (all by default).
    #[arg(long)]
    limit: Option<usize>,
    /// Output: safetensors with `features` f32 [N,12] and `pixel` u32 [N].
    #[arg(long)]
    out: PathBuf,
}

pub fn run(a: FeaturesArgs) -> Result<()> {
    let budget = a.budget;
    let scene = load_scene(&a.scene, &a.common)?;
    let (fl, _) = rasterize_view(&scene, a.view, &a.common)?;
    let (_, f) = budget.resolve(
        &dhoit_runtime::budget::DKB,
        fl.pixel_count() as u64,
        fl.fragment_count() as u64,
    )?;
    let feats = dhoit_runtime::importance::features(&fl, f);
    let covered: Vec<usize> = (0..fl.pixel_count()).filter(|&p| fl.count(p) > 0).collect();
    let keep: Vec<usize> = match a.limit {
        Some(l) if l > 0 && l < covered.len() => {
            (0..l).map(|i| covered[i * covered.len() / l]).collect()
        }
        Some(0) => bail!("--limit must be positive"),
        _ => covered,
    };
    let rows: Vec<f32> = keep.iter().flat_map(|&p| feats[p]).collect();
    let pixels: Vec<u32> = keep.iter().map(|&p| p as u32).collect();
    let meta = std::collections::HashMap::from([
        ("scene".to_string(), scene.name.clone()),
        ("view".to_string(), a.view.to_string()),
        ("width".to_string(), fl.width.to_string()),
        ("height".to_string(), fl.height.to_string()),
        ("budget_fragments".to_string(), f.to_string()),
    ]);
    tensors::write(
        &a.out,
        &[
            Entry::f32(
                "features",
                vec![keep.len(), dhoit_runtime::importance::FEATURES],
                &rows,
            ),
            Entry::u32("pixel", vec![keep.len()], &pixels),
        ],
        meta,
    )?;
    println!("{} pixels' features -> {}", keep.len(), a.out.display());
    Ok(())
}
