//! Names every binding the shaders declare: `bindings.rs` in OUT_DIR holds a module a shader
//! (`shaders/allocate.wgsl` → `bindings::allocate`) with a constant a binding, its variable's
//! name in capitals (`@group(0) @binding(5) var<storage, read_write> state` → `STATE = 5`). The
//! host binds its buffers by those names (`wgsl::bindings`), so a binding index is written
//! once, in its shader.

use std::fmt::Write as _;
use std::path::Path;

fn main() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shaders");
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .expect("the shaders directory beside the runtime crate")
        .map(|e| e.expect("a shader's directory entry").path())
        .filter(|p| p.extension().is_some_and(|e| e == "wgsl"))
        .collect();
    files.sort();
    let mut out = String::new();
    let mut all = String::new();
    for path in files {
        println!("cargo:rerun-if-changed={}", path.display());
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        let text = std::fs::read_to_string(&path).expect("a shader's text");
        let mut consts: Vec<(String, u32)> = Vec::new();
        for (line_no, line) in text.lines().enumerate() {
            let Some((binding, name)) = declared_binding(line) else {
                continue;
            };
            let name = name.to_ascii_uppercase();
            match consts.iter().find(|(n, _)| *n == name) {
                Some((_, b)) if *b != binding => panic!(
                    "{}:{}: `{name}` is bound at {b} and at {binding}",
                    path.display(),
                    line_no + 1
                ),
                Some(_) => {}
                None => consts.push((name, binding)),
            }
        }
        if consts.is_empty() {
            continue;
        }
        writeln!(out, "/// The bindings `shaders/{stem}.wgsl` declares.").unwrap();
        writeln!(out, "pub mod {stem} {{").unwrap();
        for (name, binding) in consts {
            writeln!(out, "    pub const {name}: u32 = {binding};").unwrap();
            writeln!(all, "    (\"{stem}\", \"{name}\", {binding}),").unwrap();
        }
        writeln!(out, "}}").unwrap();
    }
    writeln!(
        out,
        "/// Every binding named above: (shader, name, binding)."
    )
    .unwrap();
    writeln!(out, "pub const ALL: &[(&str, &str, u32)] = &[\n{all}];").unwrap();
    let dest = Path::new(&std::env::var("OUT_DIR").unwrap()).join("bindings.rs");
    std::fs::write(dest, out).expect("bindings.rs in OUT_DIR");
}

/// `@group(G) @binding(N) var<...> name: T;` (or `var name: T;`, a texture or sampler) → (N,
/// name); None for any other line.
fn declared_binding(line: &str) -> Option<(u32, &str)> {
    let line = line.trim_start();
    if line.starts_with("//") {
        return None;
    }
    let rest = &line[line.find("@binding(")? + "@binding(".len()..];
    let close = rest.find(')')?;
    let binding = rest[..close].trim().parse().ok()?;
    let rest = rest[close + 1..].trim_start().strip_prefix("var")?;
    let rest = match rest.trim_start().strip_prefix('<') {
        Some(r) => &r[r.find('>')? + 1..],
        None => rest,
    };
    let name = rest
        .trim_start()
        .split(|c: char| c == ':' || c.is_whitespace())
        .next()?;
    Some((binding, name))
}
