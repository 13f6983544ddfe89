//! The training entry point: `cargo run --release -p dhoit-train` with no arguments generates
//! the default dataset from the built-in scenes (if needed), trains the network and writes
//! data/weights.safetensors with config.json and loss plot (svg, png) beside it. Same flags as `dhoit train`.

use clap::Parser;

#[derive(Parser)]
#[command(
    name = "dhoit-train",
    version,
    about = "Train the dhoit importance network on the CPU"
)]
struct Cli {
    #[command(flatten)]
    args: dhoit_train::cli::TrainArgs,
}

fn main() {
    let cli = Cli::parse();
    if let Err(e) = dhoit_train::cli::train(cli.args) {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
