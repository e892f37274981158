//! What the command line says when a user gets something wrong, and its `--help`: each
//! message names what was wrong and what would be right.

use clap::CommandFactory;
use graybox::cli::Cli;

use super::{graybox, tmp};

fn stderr_of(args: &[&str]) -> String {
    let out = graybox(args);
    assert!(!out.status.success(), "{args:?} succeeded");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Every file a command writes (`--out`) and every model, dataset and Δt it reads has a help
/// line: a bare `--out <OUT>` told nobody what is written there.
#[test]
fn every_file_and_step_argument_has_a_help_line() {
    let cli = Cli::command();
    let mut missing = vec![];
    for cmd in cli.get_subcommands() {
        for arg in cmd.get_arguments() {
            let long = arg.get_long().unwrap_or_default();
            if ["out", "model", "data", "dt"].contains(&long) && arg.get_help().is_none() {
                missing.push(format!("{} --{long}", cmd.get_name()));
            }
        }
    }
    assert!(missing.is_empty(), "without a help line: {missing:?}");
}

#[test]
fn wrong_inputs_are_named_with_what_would_be_right() {
    let arm = concat!(env!("CARGO_MANIFEST_DIR"), "/examples/urdf_arm/arm.urdf");
    // A URDF where a model file goes: said to be a template, and where it goes.
    let said = stderr_of(&["inspect", "--model", arm]);
    assert!(
        said.contains("URDF") && said.contains("--template"),
        "{said}"
    );
    // A template file with an extension graybox does not read: the extensions it does.
    let txt = tmp("arm.txt");
    std::fs::copy(arm, &txt).unwrap();
    let said = stderr_of(&["simulate", "--template", &txt, "--out", &tmp("x.json")]);
    assert!(
        said.contains(".json") && said.contains(".urdf") && said.contains("extension"),
        "{said}"
    );
    // A horizon of 0: the bound that applies here (no upper one on the command line).
    let model = tmp("dp-messages.gbx");
    let data = tmp("dp-messages.json");
    let ok = graybox(&[
        "model",
        "--template",
        "double_pendulum",
        "--dt",
        "0.01",
        "--out",
        &model,
    ]);
    assert!(ok.status.success(), "{ok:?}");
    let sim = [
        "simulate",
        "--system",
        "double_pendulum",
        "--trajectories",
        "2",
        "--steps",
        "20",
    ];
    assert!(
        graybox(&[&sim[..], &["--out", &data]].concat())
            .status
            .success()
    );
    let said = stderr_of(&[
        "eval",
        "--model",
        &model,
        "--data",
        &data,
        "--horizons",
        "0,10",
    ]);
    assert!(
        said.contains("1 or more") && !said.contains(&usize::MAX.to_string()),
        "{said}"
    );
}

/// An `http://` object-store endpoint without `AWS_ALLOW_HTTP`: the variable to set, at once
/// (every call used to fail with the HTTP client's bare "builder error").
#[test]
fn a_plain_http_object_store_names_the_variable_it_needs() {
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("g.db");
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args([
            "worker",
            "--db",
            db.to_str().unwrap(),
            "--blobs",
            "s3://bucket/prefix",
        ])
        .env("AWS_ENDPOINT", "http://127.0.0.1:1")
        .env_remove("AWS_ALLOW_HTTP")
        .envs([("AWS_REGION", "us-east-1"), ("AWS_ACCESS_KEY_ID", "k")])
        .env("AWS_SECRET_ACCESS_KEY", "s")
        .output()
        .unwrap();
    let said = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{said}");
    assert!(
        said.contains("AWS_ALLOW_HTTP=true") && said.contains("blobs"),
        "{said}"
    );
}
