//! Thin binary edge: parse, run, map errors to one line and an exit code.
//! Library errors are typed (`sphereshade::Error`); here they become
//! `anyhow` errors with the failing subcommand as context.

use anyhow::Context as _;
use clap::Parser;

use sphereshade::cli::{Cli, Exit, run};
use sphereshade::output::printable;

fn main() {
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or("warn")).init();
    let cli = match Cli::try_parse_from(sphereshade::cli::negative_values(std::env::args_os())) {
        Ok(cli) => cli,
        Err(e) if !e.use_stderr() => {
            // --help, --version: clap's text on stdout, exit 0.
            let _ = e.print();
            return;
        }
        Err(e) => {
            // Usage errors follow the error contract too: one line, exit 1.
            eprintln!(
                "sphereshade: {}",
                printable(&usage_line(&e.render().to_string()))
            );
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
            eprintln!("{}", printable(&one_line(&e)));
            std::process::exit(1);
        }
    }
}

/// The error and its causes on one line, as `{:#}` joins them, but a cause
/// that the message before it already ends with (an I/O error whose
/// Display names its path and its source) is said once.
fn one_line(e: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if line.ends_with(&text) {
            continue;
        }
        if !line.is_empty() {
            line.push_str(": ");
        }
        line.push_str(&text);
    }
    line
}

/// clap's message on one line: its first line and the indented lines that
/// continue it (the missing arguments of "the following required arguments
/// were not provided:"), up to the blank line before the usage.
fn usage_line(text: &str) -> String {
    let mut lines = text.lines();
    let mut line = lines.next().unwrap_or("invalid command line").to_string();
    let more: Vec<&str> = lines
        .take_while(|l| !l.trim().is_empty())
        .filter(|l| l.starts_with(' '))
        .map(str::trim)
        .collect();
    if !more.is_empty() {
        line.push(' ');
        line.push_str(&more.join(", "));
    }
    line
}
