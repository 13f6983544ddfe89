//! How far two pictures are apart: the channels (8-bit) that differ, by how much at most, the
//! sum of the differences, and whether that is within `--max` (exit 1 where it is not). What
//! `make test` holds the viewer example's frames to its exact frame with.
//!
//!     cargo run --release --example image_diff -- A.png B.png [--max STEPS] [--pixels SHARE]

fn main() {
    if let Err(e) = run() {
        eprintln!("image_diff: {e}");
        std::process::exit(2);
    }
}

fn run() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: image_diff A.png B.png [--max STEPS] [--pixels SHARE]";
    let (a, b) = match (args.first(), args.get(1)) {
        (Some(a), Some(b)) => (a, b),
        _ => return Err(usage.into()),
    };
    let flag = |name: &str, default: f64| -> Result<f64, Box<dyn std::error::Error>> {
        match args.iter().position(|x| x == name) {
            Some(i) => Ok(args.get(i + 1).ok_or(usage)?.parse()?),
            None => Ok(default),
        }
    };
    // At most `max` steps in any channel, and beyond one step in at most `pixels` of them.
    let (max, pixels) = (flag("--max", 0.0)?, flag("--pixels", 0.0)?);
    let read = |p: &str| {
        image::open(p)
            .map(|i| i.to_rgb8())
            .map_err(|e| format!("{p}: {e}"))
    };
    let (a_img, b_img) = (read(a)?, read(b)?);
    if a_img.dimensions() != b_img.dimensions() {
        return Err(format!(
            "{a} is {:?}, {b} {:?}",
            a_img.dimensions(),
            b_img.dimensions()
        )
        .into());
    }
    let (mut differ, mut beyond_one, mut most, mut sum) = (0usize, 0usize, 0u8, 0u64);
    for (x, y) in a_img.as_raw().iter().zip(b_img.as_raw()) {
        let d = x.abs_diff(*y);
        sum += d as u64;
        differ += (d > 0) as usize;
        beyond_one += (d > 1) as usize;
        most = most.max(d);
    }
    let n = a_img.as_raw().len();
    let share = beyond_one as f64 / n as f64;
    println!(
        "{a} against {b}: {differ} of {n} channels differ, {beyond_one} by more than one step, by at most {most}; sum {sum}"
    );
    if most as f64 > max || share > pixels {
        eprintln!(
            "image_diff: beyond --max {max} (or more than {pixels} of the channels past one step)"
        );
        std::process::exit(1);
    }
    Ok(())
}
