//! `cargo bench`: the `sphereshade bench --quick` matrix through the same
//! library code path (harness = false). Extra arguments after `--` are passed
//! on, e.g. `cargo bench -- --atoms 1000000 --shadows none,issm`.

use clap::Parser;

#[derive(Parser)]
struct BenchCli {
    #[command(flatten)]
    args: sphereshade::bench::BenchArgs,
}

fn main() {
    // cargo passes `--bench`; drop it before parsing our own flags.
    let mut argv: Vec<String> = std::env::args().filter(|a| a != "--bench").collect();
    if !argv.iter().any(|a| a == "--json") {
        argv.extend(["--json".into(), "target/bench-frame.json".into()]);
    }
    if argv.len() <= 3 {
        argv.push("--quick".into());
    }
    let cli = BenchCli::parse_from(argv);
    match sphereshade::bench::main(&cli.args) {
        Ok(0) => {}
        Ok(n) => {
            eprintln!("bench: {n} validation message(s)");
            std::process::exit(3);
        }
        Err(e) => {
            eprintln!("bench: error: {e}");
            std::process::exit(1);
        }
    }
}
