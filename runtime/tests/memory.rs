//! Memory that follows the scene: a k-buffer whose budget holds every fragment allocates what
//! the exact A-buffer does (paper 004's exact memory: 8-byte keys, the image the application's
//! own target, counted for no method) and renders it exactly, on the CPU and the GPU alike.
//! Needs a GPU adapter (lavapipe in CI); DHOIT_SKIP_GPU=1 skips explicitly.

mod common;

use common::{RenderMethod, gpu};
use dhoit_runtime::budget::{self, Budget};
use dhoit_runtime::frame::{self, Method, Options, Renderer};
use dhoit_runtime::gpu::Slots;
use dhoit_runtime::mlp::{Mlp, Precision};
use dhoit_runtime::raster::rasterize;
use dhoit_runtime::scene::{self, Camera};

const BG: [f32; 3] = [0.9, 0.85, 0.8];

#[test]
fn a_budget_that_holds_every_fragment_allocates_and_renders_the_abuffer() {
    let Some(g) = gpu() else { return };
    let mlp = Mlp::random(2);
    let size = (96, 72);
    let mut truncated = 0;
    for name in ["cad", "covers", "particles"] {
        let s = scene::load(name, Default::default()).unwrap();
        let cam = Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, size);
        let fl = rasterize(&s, &cam, size).unwrap();
        let (px, n) = (fl.pixel_count() as u64, fl.fragment_count() as u64);
        let exact = budget::ABUFFER.allocated_bytes(px, n);
        // By hand: 6 bytes a pixel (a 16-bit count, two to a word; a 32-bit offset), 8 a
        // fragment, the fixed buffers and the prefix sum's block totals.
        let blocks = (4 * px.div_ceil(budget::SCAN_BLOCK)).max(16);
        assert_eq!(px % 2, 0);
        assert_eq!(exact, 6 * px + 8 * n + 256 + 4 + 16 + 16 + blocks);
        let reference = g
            .render(&s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
            .unwrap();
        assert_eq!(reference.allocated_bytes, exact, "{name}: the GPU A-buffer");
        let holding = [
            Budget::Share(1_000_000),
            Budget::SlotsPerPixel((n as f64 / px as f64).ceil() + 1.0),
            Budget::Bytes(exact),
        ];
        for b in holding {
            let opts = Options {
                weights: Some(&mlp),
                ..Options::new(b, BG)
            };
            let r = Renderer::new(&fl, opts);
            let abuffer = r.render(Method::Abuffer).unwrap();
            for m in [Method::Fkb, Method::Vkb, Method::Dkb, Method::Optimal] {
                let a = r.allocate(m).unwrap();
                assert!(a.exact, "{name} {b} {m}: the budget holds every fragment");
                let slots = Slots::for_method(m, &a, &opts).unwrap();
                assert!(
                    matches!(slots, dhoit_runtime::gpu::Slots::Exact),
                    "{name} {b} {m}: the A-buffer's passes"
                );
                let cpu = r.composite(a.clone());
                assert_eq!(cpu.allocated_bytes, exact, "{name} {b} {m}: CPU bytes");
                assert_eq!(cpu.image, abuffer.image, "{name} {b} {m}: CPU image");
                let gpu = g.render(&s, &cam, size, BG, slots).unwrap();
                assert_eq!(gpu.allocated_bytes, exact, "{name} {b} {m}: GPU bytes");
                assert_eq!(gpu.image, reference.image, "{name} {b} {m}: GPU image");
            }
        }
        // A byte less than the A-buffer needs: a k-buffer, which never allocates more than M, or
        // a refusal where M does not hold the method's fixed cost (shallow frames: the exact
        // answer is then cheaper than any k-buffer; the memory issue's open part).
        let m_bytes = exact - 1;
        let opts = Options {
            weights: Some(&mlp),
            ..Options::new(Budget::Bytes(m_bytes), BG)
        };
        let r = Renderer::new(&fl, opts);
        for m in [Method::Vkb, Method::Dkb, Method::Optimal] {
            let a = match r.allocate(m) {
                Ok(a) => a,
                Err(dhoit_runtime::Error::Budget(..)) => {
                    // Its fixed cost, one slot and the tails its pixels may keep then.
                    let occ = budget::Occupancy::of(&fl.counts());
                    assert!(
                        opts.layout(m).reserved_bytes(px, 1, &occ) > m_bytes,
                        "{name} {m}: refused"
                    );
                    eprintln!("{name} {m}: its fixed cost exceeds the A-buffer's whole frame");
                    continue;
                }
                Err(e) => panic!("{name} {m}: {e}"),
            };
            assert!(!a.exact, "{name} {m}: one byte short");
            let slots = Slots::for_method(m, &a, &opts).unwrap();
            let cpu = r.composite(a.clone());
            assert!(
                cpu.allocated_bytes < exact,
                "{name} {m}: {}",
                cpu.allocated_bytes
            );
            let gpu = g.render(&s, &cam, size, BG, slots).unwrap();
            assert!(
                gpu.allocated_bytes < exact,
                "{name} {m}: GPU {}",
                gpu.allocated_bytes
            );
            truncated += 1;
        }
    }
    // The deep scene's VKB and optimal allocation ran below the A-buffer's bytes (DKB's
    // weights alone, 40 KiB, are more than that whole frame's A-buffer at 96x72).
    assert!(truncated >= 2, "{truncated} k-buffer frames one byte short");
}

#[test]
fn dkb_counts_the_bytes_of_the_network_it_runs_on_the_cpu_and_the_gpu() {
    let Some(g) = gpu() else { return };
    let s = scene::load("particles", Default::default()).unwrap();
    let size = (96, 72);
    let cam = Camera::orbit(&s, 1, scene::DEFAULT_VIEWS, size);
    let fl = rasterize(&s, &cam, size).unwrap();
    let px = fl.pixel_count() as u64;
    // (network, precision, its weights' bytes by hand: 28 header words, then the padded
    // parameters, 9,988 or 356, one a word at f32 and two at f16, in whole vec4s).
    let nets = [
        (Mlp::random(2), Precision::F32, 40_064),
        (Mlp::random(2), Precision::F16, 20_096),
        (Mlp::random_sized(2, 16, 8), Precision::F32, 1_536),
        (Mlp::random_sized(2, 16, 8), Precision::F16, 832),
    ];
    for (net, p, weights) in nets {
        let mlp = net.at_precision(p).unwrap();
        let label = format!("{}-{} {p}", mlp.h1, mlp.h2);
        let opts = Options {
            weights: Some(&mlp),
            ..Options::new(Budget::Share(250_000), BG).always_approximate()
        };
        // The layout: the default network's fixed cost less its weights, plus this one's.
        let layout = opts.layout(Method::Dkb);
        assert_eq!(
            layout.fixed_bytes(px) + budget::MLP_UNIFORM_BYTES,
            budget::DKB.fixed_bytes(px) + weights,
            "{label}"
        );
        let r = Renderer::new(&fl, opts);
        let a = r.allocate(Method::Dkb).unwrap();
        assert!(!a.exact, "{label}: 25% truncates");
        let slots = Slots::for_method(Method::Dkb, &a, &opts).unwrap();
        let cpu = r.composite(a.clone());
        // Its fixed bytes, the network's list and the pool made for F and the occupancy.
        let want = common::kbuffer_bytes(&layout, &cpu.k, &fl.counts(), a.budget_fragments);
        assert_eq!(cpu.allocated_bytes, want, "{label}: CPU bytes");
        // The GPU counts the buffers it creates: the weights uniform among them.
        let gpu = g.render_method(&s, &cam, size, BG, slots).unwrap();
        let bases = &gpu.slots.as_ref().unwrap().1;
        let gpu_k: Vec<u32> = bases.windows(2).map(|b| b[1] - b[0]).collect();
        // n(p) as the CPU counts it (this frame's rasterizers agree on every pixel's count).
        let bytes = common::kbuffer_bytes(&layout, &gpu_k, &fl.counts(), a.budget_fragments);
        assert_eq!(gpu.allocated_bytes, bytes, "{label}: GPU bytes");
        // Equal bytes give the others what DKB with this network needs.
        let eq = Options {
            equal: dhoit_runtime::frame::Equal::Bytes,
            ..opts
        };
        let m = Renderer::new(&fl, eq).budget().unwrap();
        let (dkb_m, _) = Budget::Share(250_000)
            .resolve_counted(&layout, px, &budget::Occupancy::of(&fl.counts()))
            .unwrap();
        assert_eq!(m, Budget::Bytes(dkb_m), "{label}: equal bytes");
    }
}

/// A memory-bounded method never costs more than the exact answer: with the default options a
/// k-buffer whose budget would cost at least the exact A-buffer's bytes renders the A-buffer
/// (exact, with its memory), on the CPU and on the GPU; a frame deep enough for the method to
/// be cheaper runs the method. Off (`always_approximate`), the same shallow frames allocate
/// more than the A-buffer: what the cap saves.
#[test]
fn a_kbuffer_never_allocates_more_than_the_exact_abuffer() {
    let Some(g) = gpu() else { return };
    let mlp = Mlp::random(5);
    let size = (96, 72);
    let budgets = ["10%", "25%", "50%", "75%", "1fpp", "2fpp", "200KB"];
    let kbuffers = [Method::Fkb, Method::Vkb, Method::Dkb, Method::Optimal];
    let (mut capped, mut dearer_uncapped, mut cheaper) = (0, 0, 0);
    let (mut gpu_capped, mut gpu_dearer_uncapped, mut gpu_cheaper) = (0, 0, 0);
    let mut scenes: Vec<(String, scene::Scene)> = ["cad", "covers", "particles", "hair"]
        .iter()
        .map(|n| (n.to_string(), scene::load(n, Default::default()).unwrap()))
        .collect();
    scenes.push(("100 layers".into(), common::layers(100)));
    for (name, s) in &scenes {
        let cam = Camera::orbit(s, 0, scene::DEFAULT_VIEWS, size);
        let fl = rasterize(s, &cam, size).unwrap();
        let (px, n) = (fl.pixel_count() as u64, fl.fragment_count() as u64);
        let exact = budget::ABUFFER.allocated_bytes(px, n);
        let reference = g
            .render(s, &cam, size, BG, dhoit_runtime::gpu::Slots::Exact)
            .unwrap();
        let gpu_n = reference.fragments.as_ref().unwrap().fragment_count() as u64;
        let occ = budget::Occupancy::of(&fl.counts());
        let gpu_occ = budget::Occupancy::of(&reference.fragments.as_ref().unwrap().counts());
        for b in budgets {
            let opts = Options {
                weights: Some(&mlp),
                ..Options::new(Budget::parse(b).unwrap(), BG)
            };
            let r = Renderer::new(&fl, opts);
            let abuffer = r.render(Method::Abuffer).unwrap();
            let uncapped = Renderer::new(&fl, opts.always_approximate());
            for m in kbuffers {
                let a = match r.allocate(m) {
                    Ok(a) => a,
                    // FKB below a slot a pixel, or a byte budget below the method's fixed cost.
                    Err(dhoit_runtime::Error::Budget(..)) => continue,
                    Err(e) => panic!("{name} {b} {m}: {e}"),
                };
                let f = r.composite(a.clone());
                assert!(
                    f.allocated_bytes <= exact,
                    "{name} {b} {m}: {} bytes, the A-buffer {exact}",
                    f.allocated_bytes
                );
                if a.budget_fragments >= n {
                    continue;
                }
                // Uncapped, FKB below a slot a pixel is refused.
                let own = uncapped.render(m).ok();
                if a.exact {
                    // Capped: the A-buffer's image and bytes, where the method would spend at
                    // least as much.
                    assert_eq!(f.image, abuffer.image, "{name} {b} {m}");
                    assert_eq!(f.allocated_bytes, exact, "{name} {b} {m}");
                    let reserved =
                        frame::reserved_bytes(m, &opts.layout(m), px, a.budget_fragments, &occ);
                    assert!(reserved >= exact, "{name} {b} {m}");
                    dearer_uncapped += usize::from(own.is_some_and(|o| o.allocated_bytes > exact));
                    capped += 1;
                } else {
                    let own = own.expect("the method's own frame");
                    assert_eq!(f.image, own.image, "{name} {b} {m}: the method itself");
                    cheaper += 1;
                }
                // The GPU follows the CPU's decision, with the bytes it creates counted, held
                // to its own A-buffer (its rasterizer may differ from the CPU's by a fragment
                // where an edge passes through a pixel centre).
                if m == Method::Dkb || (m == Method::Vkb && b == "25%") {
                    let gpu_exact = reference.allocated_bytes;
                    let slots = Slots::for_method(m, &a, &opts).unwrap();
                    let gf = g.render(s, &cam, size, BG, slots).unwrap();
                    assert!(
                        gf.allocated_bytes <= gpu_exact,
                        "{name} {b} {m}: GPU bytes {} (CPU {}), its A-buffer {gpu_exact}",
                        gf.allocated_bytes,
                        f.allocated_bytes
                    );
                    if a.exact {
                        assert_eq!(gf.allocated_bytes, gpu_exact, "{name} {b} {m}: GPU bytes");
                        assert_eq!(gf.image, reference.image, "{name} {b} {m}: GPU image");
                    }
                    // Given its slots directly, as an application calls it (no CPU count or
                    // allocation), the GPU decides on its own count.
                    let direct = match m {
                        Method::Dkb => Slots::Dkb(&mlp, a.fragment_budget.into()),
                        _ => Slots::Vkb(opts.vkb, a.fragment_budget.into()),
                    };
                    let gd = g.render(s, &cam, size, BG, direct).unwrap();
                    let f = a.fragment_budget.of(gpu_n);
                    let decide = f >= gpu_n
                        || frame::exact_is_no_dearer(m, &opts.layout(m), px, f, &gpu_occ);
                    assert_eq!(gd.exact, decide, "{name} {b} {m}: the GPU's decision");
                    assert!(
                        gd.allocated_bytes <= gpu_exact,
                        "{name} {b} {m}: GPU bytes {} given its slots, its A-buffer {gpu_exact}",
                        gd.allocated_bytes
                    );
                    // The method's own frame, from the buffers it creates: dearer than the
                    // A-buffer only where the GPU took the A-buffer.
                    let own = g.render_method(s, &cam, size, BG, direct).unwrap();
                    assert!(
                        !own.exact && own.slots.is_some(),
                        "{name} {b} {m}: the method"
                    );
                    if decide {
                        assert_eq!(gd.image, reference.image, "{name} {b} {m}: GPU image");
                        assert_eq!(gd.allocated_bytes, gpu_exact, "{name} {b} {m}: GPU bytes");
                        assert!(gd.slots.is_none(), "{name} {b} {m}: the A-buffer's passes");
                        gpu_capped += 1;
                        gpu_dearer_uncapped += usize::from(own.allocated_bytes > gpu_exact);
                    } else {
                        assert!(own.allocated_bytes < gpu_exact, "{name} {b} {m}: own bytes");
                        assert_eq!(gd.image, own.image, "{name} {b} {m}: the method itself");
                        assert_eq!(gd.allocated_bytes, own.allocated_bytes, "{name} {b} {m}");
                        gpu_cheaper += 1;
                    }
                }
            }
        }
    }
    eprintln!(
        "{capped} frames capped at the A-buffer ({dearer_uncapped} of them dearer uncapped), \
         {cheaper} cheaper than it"
    );
    assert!(
        capped >= 10 && dearer_uncapped >= 10,
        "{capped} {dearer_uncapped}"
    );
    // The deep frame's methods run (every budget but the bytes one truncates below the
    // A-buffer's 809 bytes a pixel).
    assert!(cheaper >= 10, "{cheaper}");
    eprintln!(
        "GPU given its slots: {gpu_capped} frames capped ({gpu_dearer_uncapped} of them dearer \
         uncapped), {gpu_cheaper} cheaper"
    );
    assert!(
        gpu_capped >= 10 && gpu_dearer_uncapped >= 10 && gpu_cheaper >= 3,
        "{gpu_capped} {gpu_dearer_uncapped} {gpu_cheaper}"
    );
}

/// The table of docs/device.md ("what each method needs from the device") is the layout tables'
/// own: regenerated here from `budget::layout` and required to appear in the page verbatim, so
/// the page cannot drift from the buffers the pipelines create.
#[test]
fn the_device_page_lists_the_buffers_the_layouts_count() {
    let mut table = String::from(
        "| method | bytes a pixel | its buffers (bytes a pixel) | a slot | a pooled tail | in the pool first | fixed bytes | weights |\n\
         |---|---:|---|---:|---:|---|---:|---:|\n",
    );
    for m in [
        "abuffer",
        "fkb",
        "mlab",
        "wboit",
        "mboit",
        "linked-list",
        "optimal",
        "vkb",
        "dkb",
    ] {
        let l = budget::layout(m).unwrap();
        let buffers: Vec<String> = l
            .per_pixel
            .iter()
            .map(|(label, b)| format!("`{label}` {b}"))
            .chain(l.marks.map(|label| {
                format!(
                    "`{label}` 4 every {} pixels",
                    dhoit_runtime::shared::MARK_BITS / 2
                )
            }))
            .collect();
        let fixed: u64 = l.fixed.iter().map(|b| b.1).sum();
        table += &format!(
            "| {m} | {} | {} | {} | {} | {} | {fixed} | {} |\n",
            l.per_pixel_bytes(),
            match buffers.is_empty() {
                true => "-".to_string(),
                false => buffers.join(", "),
            },
            l.slot_bytes,
            l.tail_bytes,
            match l.pool_state {
                Some(ps) => format!(
                    "a record of {} B a pixel of 3 fragments or more and the network's list, {} B a record, all at once ({} batch; up to {} where a byte budget does not hold them), then the marks 4 B every {} pixels (a bit a pixel, a count every 32)",
                    ps.record_bytes,
                    ps.list_bytes,
                    ps.batches,
                    dhoit_runtime::budget::MOST_RECORD_BATCHES,
                    dhoit_runtime::shared::MARK_BITS / 2,
                ),
                None => "-".into(),
            },
            l.weights
        );
    }
    let page = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/device.md"),
    )
    .unwrap();
    assert!(
        page.contains(&table),
        "docs/device.md should hold the layout tables as they are:\n{table}"
    );
}
