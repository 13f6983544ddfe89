//! `dhoit scenes` and `dhoit export`: what scenes there are, and a scene written as glTF.

use anyhow::{Result, bail};
use clap::Args;
use dhoit_runtime::scene::{self, Opacity};
use std::path::{Path, PathBuf};

pub fn list() -> Result<()> {
    let folder = std::env::var_os("DHOIT_SCENES");
    if let Some(dir) = folder.as_deref().map(Path::new).filter(|d| !d.is_dir()) {
        bail!(
            "DHOIT_SCENES={}: not a folder (unset it, or point it at a folder of .gltf/.glb \
             files)",
            dir.display()
        );
    }
    println!("{:<12} {:>10}  description", "built-in", "triangles");
    for (name, desc) in scene::procedural::BUILTIN {
        let s = scene::procedural::build(name).expect("built-in scene");
        println!("{:<12} {:>10}  {}", name, s.triangle_count(), desc);
    }
    match folder {
        Some(dir) => {
            let dir = Path::new(&dir);
            println!("\nglTF files under {}:", dir.display());
            let mut files = Vec::new();
            find_gltf(dir, &mut files, 0);
            files.sort();
            if files.is_empty() {
                println!("(none: no .gltf or .glb file in it or its subfolders, 4 deep)");
            }
            for f in files {
                match scene::load(&f.to_string_lossy(), Opacity::Material) {
                    Ok(s) => println!("{:>10}  {}", s.triangle_count(), f.display()),
                    Err(e) => println!("{:>10}  {} ({e})", "error", f.display()),
                }
            }
        }
        None => println!("\n(set DHOIT_SCENES to a folder of .gltf/.glb files to list them too)"),
    }
    Ok(())
}

fn find_gltf(dir: &Path, out: &mut Vec<PathBuf>, depth: usize) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() && depth < 4 {
            find_gltf(&p, out, depth + 1);
        } else if p.extension().is_some_and(|x| x == "gltf" || x == "glb") {
            out.push(p);
        }
    }
}

#[derive(Args)]
pub struct ExportArgs {
    /// A built-in scene name (`cad`, `particles:7`) or a .gltf/.glb path.
    #[arg(long)]
    scene: String,
    /// The .glb file to write (written whole or not at all).
    #[arg(long)]
    out: PathBuf,
    /// Give every surface this opacity instead of keeping the scene's own alpha.
    #[arg(long)]
    opacity: Option<f32>,
}

pub fn export(a: ExportArgs) -> Result<()> {
    if !a
        .out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
    {
        bail!(
            "--out {}: export writes binary glTF, give a .glb file name",
            a.out.display()
        );
    }
    let opacity = a.opacity.map_or(Opacity::Material, Opacity::Uniform);
    let s = scene::load(&a.scene, opacity)?;
    scene::gltf::export(&s, &a.out)?;
    println!(
        "{}: {} triangles -> {}",
        s.name,
        s.triangle_count(),
        a.out.display()
    );
    Ok(())
}
