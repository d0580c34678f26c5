//! Thin binary edge: parse, run, map errors to one line and an exit code.

use clap::Parser;
use sphereshade::cli::{Cli, Exit, run};

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = Cli::parse();
    match run(cli) {
        Ok(Exit::Ok) => {}
        Ok(Exit::ValidationMessages(n)) => {
            eprintln!("sphereshade: {n} validation message(s) reported");
            std::process::exit(3);
        }
        Err(e) => {
            eprintln!("sphereshade: error: {e}");
            std::process::exit(1);
        }
    }
}
