// The A-buffer's per-pixel insertion sort, in place over `keys[start..end)` (each the 64-bit
// capture key, depth bits high and RGBA8 low), prepended to the passes that sort a pixel's
// stored fragments and declare `keys` (and `primitives`, each fragment's submission index,
// which the A-buffer stores only for MLAB and the tests' readback): front to back by key for
// the exact blend (equal keys are equal fragments: any order blends alike, as
// fragment::sort_front_to_back), submission order for MLAB (the primitives sorted alongside).
// Every step ticks the loop counter (lavapipe's limit, see common.wgsl).

// Front to back by key; with `with_primitives` the submission indices move alongside and break
// ties, as fragment::sort_front_to_back (the tests read them back).
fn sort_keys(start: u32, end: u32, with_primitives: bool) {
    for (var i = start + 1u; i < end; i++) {
        tick();
        let k = keys[i];
        var q = 0u;
        if (with_primitives) {
            q = primitives[i];
        }
        var j = i;
        loop {
            if (j <= start) {
                break;
            }
            let before = keys[j - 1u];
            var after = k < before;
            if (with_primitives) {
                after = after || (k == before && q < primitives[j - 1u]);
            }
            if (!after) {
                break;
            }
            tick();
            keys[j] = before;
            if (with_primitives) {
                primitives[j] = primitives[j - 1u];
            }
            j--;
        }
        keys[j] = k;
        if (with_primitives) {
            primitives[j] = q;
        }
    }
}

fn sort_by_submission(start: u32, end: u32) {
    for (var i = start + 1u; i < end; i++) {
        tick();
        let k = keys[i];
        let q = primitives[i];
        var j = i;
        while (j > start && q < primitives[j - 1u]) {
            tick();
            keys[j] = keys[j - 1u];
            primitives[j] = primitives[j - 1u];
            j--;
        }
        keys[j] = k;
        primitives[j] = q;
    }
}
