//! Thin binary edge: parse, run, map errors to one line and an exit code.
//! Library errors are typed (`sphereshade::Error`); here they become
//! `anyhow` errors with the failing subcommand as context.

use anyhow::Context as _;
use clap::Parser;

use sphereshade::cli::{Cli, Exit, run};
use sphereshade::output::printable;

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help, --version: clap's text on stdout, exit 0.
            let _ = e.print();
            return;
        }
        Err(e) => {
            // Usage errors follow the error contract too: one line, exit 1.
            let text = e.render().to_string();
            let line = text.lines().next().unwrap_or("invalid command line");
            eprintln!("sphereshade: {}", printable(line));
            std::process::exit(1);
        }
    };
    let ran: anyhow::Result<Exit> = run(cli).context("sphereshade: error");
    match ran {
        Ok(Exit::Ok) => {}
        Ok(Exit::ValidationMessages(n)) => {
            eprintln!("sphereshade: {n} validation message(s) reported");
            std::process::exit(3);
        }
        Err(e) => {
            // `{:#}` joins the context and the error on one line; quoted
            // input (file contents, names) cannot break it or reach the
            // terminal as control sequences.
            eprintln!("{}", printable(&format!("{e:#}")));
            std::process::exit(1);
        }
    }
}
