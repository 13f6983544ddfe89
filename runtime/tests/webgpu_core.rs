//! Every method that needs no 64-bit integer on WebGPU's core device: a device opened with no
//! feature and wgpu's default limits (`Gpu::portable`, 8 storage buffers a stage), as a browser
//! gives it. Its frames are the 64-bit device's, bit for bit, and their twins'; equal depths
//! give one image in every submission order.

mod common;

use common::{RenderMethod, core, identity, wide};
use dhoit_runtime::composite;
use dhoit_runtime::gpu::{Capture, FrameOptions, Slots};
use dhoit_runtime::scene::Camera;

const BG: [f32; 3] = [0.9, 0.8, 1.0];

fn bits(img: &composite::Image) -> Vec<u32> {
    img.data.iter().flatten().map(|x| x.to_bits()).collect()
}

/// The core device has no feature and wgpu's default limits, and builds no pass that uses
/// 64-bit integers; the 64-bit device builds them.
#[test]
fn the_core_device_is_webgpus_and_runs_without_64_bit_integers() {
    let Some(c) = core() else { return };
    let d = c.device();
    assert_eq!(d.features(), wgpu::Features::empty());
    assert_eq!(d.limits().max_storage_buffers_per_shader_stage, 8);
    assert!(!c.is_wide() && wide().unwrap().is_wide());
}

/// A-buffer, MLAB, FKB, uploaded k, VKB and DKB (their statistics, network, plan and
/// allocation on the device), the linked list and WBOIT on the core device: the 64-bit
/// device's image bit for bit (the k-buffers' slots and tails, VKB's and DKB's importance and
/// DKB's statistics too), and FKB's and the A-buffer's their twins'. MBOIT needs
/// FLOAT32_BLENDABLE, which the core device lacks: refused by name.
#[test]
fn every_portable_method_renders_on_the_core_device_as_on_the_wide_one() {
    let Some(c) = core() else { return };
    let g = wide().unwrap();
    let (w, h) = (48, 32);
    let s = common::tied_layers(24);
    let cam = identity();
    let exact = c
        .render_method(&s, &cam, (w, h), BG, dhoit_runtime::gpu::Slots::Exact)
        .unwrap();
    let fl = exact.fragments.clone().unwrap();
    let twin = composite::composite(&fl, composite::Method::Exact, BG);
    assert!(exact.image.max_abs_diff(&twin) <= 1e-5, "the A-buffer");
    let px = (w * h) as usize;
    let k: Vec<u32> = (0..px).map(|p| (p % 6) as u32).collect();
    let total = fl.fragment_count() as u64;
    let weights = common::committed_weights();
    let runs: [(&str, Slots); 13] = [
        ("dkb F = 1/4", Slots::Dkb(&weights, (total / 4).into())),
        ("dkb F = 1/2", Slots::Dkb(&weights, (total / 2).into())),
        ("dkb 1 fpp", Slots::Dkb(&weights, (px as u64).into())),
        (
            "vkb F = 1/4",
            Slots::Vkb(Default::default(), (total / 4).into()),
        ),
        (
            "vkb F = 1/2",
            Slots::Vkb(Default::default(), (total / 2).into()),
        ),
        (
            "vkb 1 fpp",
            Slots::Vkb(Default::default(), (px as u64).into()),
        ),
        ("abuffer", Slots::Exact),
        ("mlab", Slots::Mlab(3)),
        ("fkb k = 1", Slots::Uniform(1)),
        ("fkb k = 5", Slots::Uniform(5)),
        ("uploaded k", Slots::PerPixel(&k)),
        (
            "linked list",
            Slots::LinkedList {
                nodes: fl.fragment_count() as u64,
                sorted: 4,
            },
        ),
        ("wboit", Slots::Wboit(Default::default())),
    ];
    for (label, slots) in runs {
        let a = g.render_method(&s, &cam, (w, h), BG, slots).unwrap();
        let b = c.render_method(&s, &cam, (w, h), BG, slots).unwrap();
        assert!(
            bits(&a.image) == bits(&b.image),
            "{label}: the images differ"
        );
        assert!(a.slots == b.slots, "{label}: the slots differ");
        assert!(
            a.importance == b.importance,
            "{label}: the importance differs"
        );
        assert!(a.stats == b.stats, "{label}: the statistics differ");
        if a.slots.is_some() {
            assert!(
                b.variants.contains(&"capture: portable")
                    && !a.variants.contains(&"capture: portable"),
                "{label}: {:?} / {:?}",
                a.variants,
                b.variants
            );
        }
        if let Slots::Uniform(k) = slots {
            let kk = vec![k; px];
            let t = composite::composite(&fl, composite::Method::Hybrid(&kk), BG);
            assert!(b.image.max_abs_diff(&t) <= 1e-5, "{label}: from its twin");
        }
        eprintln!("{label}: the core device's image is the wide device's");
    }
    let e = c
        .render_method(&s, &cam, (w, h), BG, Slots::Mboit(Default::default()))
        .unwrap_err()
        .to_string();
    assert!(e.contains("FLOAT32_BLENDABLE"), "{e}");
}

/// Fragments of equal depth give the same image in every submission order, on both devices and
/// with both captures: the slots keep equal depths in the order of their colours.
#[test]
fn equal_depths_give_one_image_in_every_submission_order() {
    let Some(c) = core() else { return };
    let g = wide().unwrap();
    let size = (24, 16);
    let s = common::tied_layers(30);
    let cam: Camera = identity();
    let wide = FrameOptions::default().always_approximate();
    let portable = FrameOptions {
        capture: Capture::Portable,
        ..wide
    };
    for slots in [Slots::Exact, Slots::Uniform(2), Slots::Uniform(7)] {
        let first = g.render_method(&s, &cam, size, BG, slots).unwrap();
        for seed in 0..4 {
            let shuffled = s.shuffled(seed);
            for (name, dev, opts) in [
                ("wide device, wide capture", g, &wide),
                ("wide device, portable capture", g, &portable),
                ("core device", c, &wide),
            ] {
                let f = dev
                    .render_with(opts, &shuffled, &cam, size, BG, slots)
                    .unwrap();
                assert!(
                    bits(&f.image) == bits(&first.image),
                    "{slots:?}, {name}, shuffle {seed}: another image"
                );
            }
        }
    }
}
