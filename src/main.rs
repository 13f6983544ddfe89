//! `dhoit`: deep hybrid order-independent transparency: render, compare and benchmark.
//!
//! One module per command; what several share (view options, loading) is in [`args`].

use clap::{Parser, Subcommand};

mod args;
mod bench;
mod compare;
mod features;
mod predict;
mod render;
mod scenes;
mod sequence;
mod trade;
mod versus;

/// `dhoit --help`'s description, its methods listed from the registry
/// ([`dhoit_runtime::method::help`]).
fn long_about() -> String {
    format!(
        "Deep hybrid order-independent transparency.\n\n\
        Renders many overlapping transparent surfaces with a k-buffer whose per-pixel k is \
        decided within a fixed memory budget, beside the exact A-buffer and the baselines.\n\n\
        Methods: {}.\n\n\
        Budgets are bytes with units (20MB, 40MiB), average fragment slots per pixel (2fpp), or \
        a share of the frame's own visible transparent fragments (25%). A budget is a cap: \
        where the exact A-buffer needs no more bytes than a k-buffer method would at its \
        budget, `render` and `compare` render the A-buffer, exact, with its memory \
        (--always-approximate renders the method's own approximation).\n\
        Scenes are built-in names (see `dhoit scenes`) or paths to .gltf/.glb files, each with \
        its own materials (opaque, masked, blended, glass; the papers' built-in families at one \
        opacity of 0.33); --opacity A gives every surface one opacity.",
        dhoit_runtime::method::help()
    )
}

#[derive(Parser)]
#[command(
    name = "dhoit",
    version,
    about = "Deep hybrid order-independent transparency",
    long_about = long_about()
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List the built-in scenes (and glTF files under $DHOIT_SCENES) with triangle counts.
    Scenes,
    /// Render one view of a scene with one method.
    Render(render::RenderArgs),
    /// Render scenes x views x budgets with several methods: a quality table, images, side-by-side
    /// pictures, report.json and report.md.
    #[command(alias = "eval")]
    Compare(compare::CompareArgs),
    /// Generate a training dataset: features and optimal-allocation targets from scenes, their
    /// glass tinted.
    Dataset(dhoit_train::cli::DatasetArgs),
    /// Train the importance network on the CPU (burn) and export safetensors weights.
    Train(dhoit_train::cli::TrainArgs),
    /// Predict importance for a features file with burn inference.
    Predict(dhoit_train::cli::PredictArgs),
    /// Score allocations from error curves, no images: optimal, VKB and the network(s) per scene
    /// and budget, as DKB/VKB and DKB/optimal ratios (fast; `compare` renders the images), the
    /// glass tinted as `compare` renders it by default.
    Score(dhoit_train::cli::ScoreArgs),
    /// Leave one family out: for each built-in scene family, a network trained without it
    /// scored against the optimal allocation on its held-out scene, beside one trained on every
    /// family; how DKB does on a kind of scene it has never seen (docs/generalise.md).
    Generalise(dhoit_train::generalise::GeneraliseArgs),
    /// Export the 12 network features of one view's covered pixels (for predict).
    Features(features::FeaturesArgs),
    /// Measure every method's GPU frame (steady frames of a persistent renderer: GPU and wall
    /// ms, each pass, DKB/VKB and DKB/A-buffer, and DKB's layout and geometry options side by
    /// side), then CPU rasterization, compositing, allocation and the network's training and
    /// inference throughput (samples a second; `--network-only` for those alone); prints JSON.
    Bench(bench::BenchArgs),
    /// The speed-accuracy trade: networks of several sizes (the default and those shipped in
    /// data/nets/) on scenes, importance-pass time and weights' bytes against MSE and FLIP,
    /// the Pareto front marked, and each network against VKB at equal bytes (its weights
    /// counted in the memory both get); trade.json, trade.md and plots.
    Trade(trade::TradeArgs),
    /// Every OIT method at equal bytes (the A-buffer, FKB, VKB, DKB, WBOIT, MBOIT, the budgeted
    /// linked list): GPU frame time against MSE and FLIP, one chart a budget, the Pareto front
    /// marked; versus.json, versus.md and plots.
    Versus(versus::VersusArgs),
    /// The network and precision with the fewest bytes of weights whose MSE on a scene is
    /// within --target of the optimal allocation's; writes its weights, precision recorded.
    Fit(trade::FitArgs),
    /// Write a scene (a built-in, or a glTF file) as binary glTF 2.0: positions, vertex colours
    /// and alpha, to open it in other tools or to test the glTF loader without real scenes.
    Export(scenes::ExportArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Scenes => scenes::list(),
        Command::Export(a) => scenes::export(a),
        Command::Render(a) => render::run(a),
        Command::Compare(a) => compare::run(a),
        Command::Dataset(a) => dhoit_train::cli::dataset(a).map_err(Into::into),
        Command::Train(a) => dhoit_train::cli::train(a).map_err(Into::into),
        Command::Predict(a) => predict::run(a),
        Command::Score(a) => dhoit_train::cli::score(a).map_err(Into::into),
        Command::Generalise(a) => dhoit_train::generalise::run(a).map_err(Into::into),
        Command::Features(a) => features::run(a),
        Command::Bench(a) => bench::run(a),
        Command::Trade(a) => trade::trade(a),
        Command::Versus(a) => versus::run(a),
        Command::Fit(a) => trade::fit(a),
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}
