//! Budget parsing and the F(M) accounting.

use dhoit_runtime::budget::{self, Budget, Occupancy};

#[test]
fn budgets_parse_with_units() {
    assert_eq!(Budget::parse("20MB").unwrap(), Budget::Bytes(20_000_000));
    assert_eq!(Budget::parse("40MiB").unwrap(), Budget::Bytes(40 << 20));
    assert_eq!(Budget::parse("1.5 GiB").unwrap(), Budget::Bytes(3 << 29));
    assert_eq!(Budget::parse("1048576").unwrap(), Budget::Bytes(1 << 20));
    assert_eq!(Budget::parse("2fpp").unwrap(), Budget::SlotsPerPixel(2.0));
    assert_eq!(Budget::parse("0.5FPP").unwrap(), Budget::SlotsPerPixel(0.5));
    for bad in [
        "",
        "MB",
        "-3MB",
        "2 parsecs",
        "nanfpp",
        "0fpp",
        "-1fpp",
        "0B",
        "1e30",
    ] {
        assert!(Budget::parse(bad).is_err(), "{bad}");
    }
}

#[test]
fn fragment_budget_follows_the_layout_and_never_overspends() {
    // DKB's pool holds state first (pooled_tails_leave_the_largest_budget_that_fits).
    for layout in [
        budget::DKB,
        budget::VKB,
        budget::FKB,
        budget::OPT,
        budget::MLAB,
    ] {
        if layout.pool_state.is_some() {
            continue;
        }
        for pixels in [1u64, 1000, 640 * 480, 1430 * 960] {
            // Before a frame is counted, pooled tails are held to one a pixel.
            let tails = pixels * layout.tail_bytes;
            for extra in [0u64, 7, 8, 1 << 20, 12_345_679] {
                let m = layout.fixed_bytes(pixels) + tails + pixels * budget::SLOT_BYTES + extra;
                let f = layout.fragment_budget(m, pixels).unwrap();
                // F(M) = floor((M - |P| S_p - S_i) / S_f), and it is the largest that fits.
                assert_eq!(
                    f,
                    (m - layout.fixed_bytes(pixels) - tails) / budget::SLOT_BYTES
                );
                assert!(layout.allocated_with_tails(pixels, f, pixels) <= m);
                assert!(layout.allocated_with_tails(pixels, f + 1, pixels) > m);
            }
            if layout.tail_bytes > 0 {
                continue;
            }
            // Below the fixed cost plus one slot per pixel: an error that says what is needed.
            let need = layout.fixed_bytes(pixels) + pixels * budget::SLOT_BYTES;
            let e = layout
                .fragment_budget(layout.fixed_bytes(pixels), pixels)
                .unwrap_err();
            assert!(e.to_string().contains(&budget::format_bytes(need)), "{e}");
        }
    }
    // Slots per pixel fix F directly; bytes follow from the layout.
    let (m, f) = Budget::SlotsPerPixel(2.0)
        .resolve(&budget::DKB, 100, 0)
        .unwrap();
    assert_eq!(f, 200);
    // Before a frame is counted: every pixel deeper, with a record (32 bytes) and a list entry
    // (4), 3,600 bytes, more than the slots and the tails every pixel may keep take (200
    // slots and two words a pixel: 3,200 bytes): the pool holds every record, one batch. In
    // up to three batches, the slots' and tails' pool holds 88 records a batch.
    let most = budget::Occupancy {
        fragments: u64::MAX,
        covered: 100,
        deep: 100,
        deeper: 100,
    };
    assert_eq!(m, budget::DKB.reserved_bytes(100, 200, &most));
    assert_eq!(m, budget::DKB.fixed_bytes(100) + 3_600);
    let ps = budget::DKB.pool_state.unwrap();
    assert_eq!(ps.batch(m - budget::DKB.fixed_bytes(100), 100), (100, 1));
    let batched = budget::DKB.with_record_batches(3);
    let m3 = batched.reserved_bytes(100, 200, &most);
    assert_eq!(m3, batched.fixed_bytes(100) + 8 * (200 + 2 * 100));
    assert_eq!(ps.batch(m3 - batched.fixed_bytes(100), 100), (88, 2));
    // A pool that holds every record gathers them in one batch; the least pool, a third of
    // them a batch (34 records, 1,224 bytes), in three.
    assert_eq!(ps.batch(3_600, 100), (100, 1));
    assert_eq!(ps.batch(1_224, 100), (34, 3));
    // No record: one batch all the same, whose gather writes every pixel's importance.
    assert_eq!(ps.batch(1_224, 0), (1, 1));
}

/// A counted frame's F(M) with pooled tails is the largest F whose fixed bytes, slots and the
/// words its pixels may take past them (a tail of two words, or the fragments it would hold:
/// up to two a covered pixel below one slot each, one a deep pixel and one a deeper above)
/// fit M, DKB's records whole in its pool, or where that leaves no slot, in up to three
/// batches: held to an exhaustive search over F.
#[test]
fn pooled_tails_leave_the_largest_budget_that_fits() {
    let pixels = 64u64;
    let mut both = [false; 2];
    for layout in [budget::VKB, budget::DKB] {
        for (covered, deep, deeper) in [
            (0u64, 0u64, 0u64),
            (1, 0, 0),
            (40, 3, 1),
            (40, 39, 20),
            (64, 64, 64),
            (20, 20, 0),
        ] {
            let occ = budget::Occupancy {
                fragments: 10_000,
                covered,
                deep,
                deeper,
            };
            let fixed = layout.fixed_bytes(pixels);
            for m in (fixed..fixed + 2_400).step_by(3) {
                let search = |l: budget::Layout| {
                    (0..=400u64)
                        .rev()
                        .find(|&f| l.reserved_bytes(pixels, f, &occ) <= m)
                        .filter(|&f| f > 0)
                };
                let batched = layout.with_record_batches(budget::MOST_RECORD_BATCHES);
                let best = search(layout).or_else(|| search(batched));
                match (layout.fragment_budget_counted(m, pixels, &occ), best) {
                    (Ok(f), Some(b)) => {
                        assert_eq!(
                            f, b,
                            "{} M {m} covered {covered} deep {deep}",
                            layout.method
                        );
                        both[usize::from(f >= covered)] = true;
                    }
                    // Refused: not even one slot fits (an empty frame needs none).
                    (Err(e), b) => {
                        assert!(b.is_none_or(|b| b == 0), "{} M {m}: {e}", layout.method);
                        assert!(e.to_string().contains("tail"), "{e}");
                    }
                    (Ok(f), None) => panic!("{} M {m}: F {f} where nothing fits", layout.method),
                }
            }
        }
    }
    // Budgets below a slot for every covered pixel and above it.
    assert_eq!(both, [true, true]);
}

/// An expected occupancy scaled up rounds every count up and never names more pixels than
/// the frame has (the stream's headroom and its resize both go through it).
#[test]
fn a_scaled_occupancy_rounds_up_within_the_frame() {
    let o = Occupancy {
        fragments: 1001,
        covered: 90,
        deep: 41,
        deeper: 3,
    };
    // 1001 x 1.25 = 1251.25, 90 x 1.25 = 112.5 (capped at 100), 41 x 1.25 = 51.25, 3.75.
    assert_eq!(
        o.scaled(1.25, 100),
        Occupancy {
            fragments: 1252,
            covered: 100,
            deep: 52,
            deeper: 4,
        }
    );
    assert_eq!(o.scaled(1.0, 1000), o);
    assert_eq!(Occupancy::most(7).scaled(2.0, 7).covered, 7);
}
