//! Budget parsing and the F(M) accounting.

use dhoit_runtime::budget::{self, Budget};

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
    for layout in [
        budget::DKB,
        budget::VKB,
        budget::FKB,
        budget::OPT,
        budget::MLAB,
    ] {
        for pixels in [1u64, 1000, 640 * 480, 1430 * 960] {
            for extra in [0u64, 7, 8, 1 << 20, 12_345_679] {
                let m = layout.fixed_bytes(pixels) + pixels * budget::SLOT_BYTES + extra;
                let f = layout.fragment_budget(m, pixels).unwrap();
                // F(M) = floor((M - |P| S_p - S_i) / S_f), and it is the largest that fits.
                assert_eq!(f, (m - layout.fixed_bytes(pixels)) / budget::SLOT_BYTES);
                assert!(layout.allocated_bytes(pixels, f) <= m);
                assert!(layout.allocated_bytes(pixels, f + 1) > m);
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
    assert_eq!(m, budget::DKB.allocated_bytes(100, 200));
}
