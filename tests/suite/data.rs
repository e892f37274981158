//! Dataset files: the JSON and CSV forms, round trips, and clear errors for bad files.

use graybox::data::Dataset;
use graybox::error::Error;
use graybox::physics::templates::Template;
use graybox::sim::{SimConfig, simulate};

fn field_of(err: Error) -> String {
    match err {
        Error::Invalid { field, .. } => field,
        other => panic!("expected an invalid-input error, got {other}"),
    }
}

const GOOD: &str = r#"{"dt":0.01,"q":[[0,1],[2,3]],"qdot":[[0,0],[1,1]],"u":[[1],[2]],"q_next":[[0,1],[2,3]],"qdot_next":[[0,0],[1,1]]}"#;

#[test]
fn json_round_trip() {
    let ds = simulate(
        &Template::Cartpole,
        Template::Cartpole.defaults(),
        &SimConfig {
            count: 20,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let back = Dataset::from_json(&ds.to_json(), None).unwrap();
    assert_eq!(ds, back);
    let g = Dataset::from_json(GOOD, None).unwrap();
    assert_eq!((g.nq, g.nv, g.m, g.count()), (2, 2, 1, 2));
}

#[test]
fn csv_matches_json() {
    let csv = "q0,q1,qdot0,qdot1,u0,q_next0,q_next1,qdot_next0,qdot_next1\n0,1,0,0,1,0,1,0,0\n2,3,1,1,2,2,3,1,1\n";
    assert_eq!(
        Dataset::from_csv(csv, 0.01).unwrap(),
        Dataset::from_json(GOOD, None).unwrap()
    );
}

/// Each bad file is refused with an error that names the offending field (and row).
#[test]
fn bad_files_name_the_field() {
    let cases: Vec<(&str, String, &str)> = vec![
        ("malformed JSON", r#"{"dt":0.01,"q":[[0,1]"#.into(), "body"),
        ("not an object", "[1,2,3]".into(), "body"),
        ("missing dt", GOOD.replace(r#""dt":0.01,"#, ""), "dt"),
        ("negative dt", GOOD.replace("0.01", "-0.01"), "dt"),
        ("dt not a number", GOOD.replace("0.01", r#""fast""#), "dt"),
        ("missing field", GOOD.replace(r#","u":[[1],[2]]"#, ""), "u"),
        (
            "ragged rows",
            GOOD.replace("[[0,1],[2,3]],\"qdot\"", "[[0,1],[2]],\"qdot\""),
            "q[1]",
        ),
        (
            "string value",
            GOOD.replace(r#""u":[[1],[2]]"#, r#""u":[[1],["x"]]"#),
            "u[1]",
        ),
        (
            "row count mismatch",
            GOOD.replace(r#""u":[[1],[2]]"#, r#""u":[[1]]"#),
            "u",
        ),
        (
            // qdot may be narrower than q (nv < nq), but qdot_next has qdot's width.
            "qdot and qdot_next of different widths",
            GOOD.replace(r#""qdot":[[0,0],[1,1]]"#, r#""qdot":[[0],[1]]"#),
            "qdot_next",
        ),
        (
            "field not an array",
            GOOD.replace(r#""u":[[1],[2]]"#, r#""u":3"#),
            "u",
        ),
        (
            "row not an array",
            GOOD.replace(r#""u":[[1],[2]]"#, r#""u":[1,2]"#),
            "u[0]",
        ),
        (
            "empty dataset",
            r#"{"dt":0.01,"q":[],"qdot":[],"u":[],"q_next":[],"qdot_next":[]}"#.into(),
            "q",
        ),
        (
            "no inputs",
            GOOD.replace(r#""u":[[1],[2]]"#, r#""u":[[],[]]"#),
            "u",
        ),
        (
            "overflowing number",
            GOOD.replace(r#""u":[[1],[2]]"#, r#""u":[[1],[1e999]]"#),
            "body",
        ),
    ];
    assert!(cases.len() >= 8);
    for (what, text, field) in cases {
        let err = Dataset::from_json(&text, None).expect_err(what);
        let msg = err.to_string();
        assert_eq!(field_of(err), field, "{what}: {msg}");
    }
}

#[test]
fn bad_csv_names_the_field() {
    let header = "q0,q1,qdot0,qdot1,u0,q_next0,q_next1,qdot_next0,qdot_next1\n";
    let cases = [
        ("bad header", "q0,qdot0,u0\n1,2\n".to_string(), "csv.header"),
        (
            "short row",
            format!("{header}0,1,0,0,1,0,1,0\n"),
            "csv.row[0]",
        ),
        (
            "not a number",
            format!("{header}0,1,0,0,x,0,1,0,0\n"),
            "u[0]",
        ),
        ("NaN", format!("{header}0,1,0,0,1,0,NaN,0,0\n"), "q_next[0]"),
        (
            "infinite",
            format!("{header}0,1,0,inf,1,0,1,0,0\n"),
            "qdot[0]",
        ),
        ("empty", String::new(), "csv"),
    ];
    for (what, text, field) in cases {
        let err = Dataset::from_csv(&text, 0.01).expect_err(what);
        let msg = err.to_string();
        assert_eq!(field_of(err), field, "{what}: {msg}");
    }
    assert_eq!(
        field_of(Dataset::from_csv(&format!("{header}0,1,0,0,1,0,1,0,0\n"), 0.0).unwrap_err()),
        "dt"
    );
    // A header with no q (or no u) columns says what the columns are, with an example.
    let msg = Dataset::from_csv("x,y,z\n1,2,3\n", 0.01)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("q0,q1,qdot0,qdot1,u0,q_next0,q_next1,qdot_next0,qdot_next1"),
        "{msg}"
    );
}

#[test]
fn split_is_seeded_and_disjoint() {
    let ds = simulate(
        &Template::Pendulum,
        Template::Pendulum.defaults(),
        &SimConfig {
            count: 50,
            ..SimConfig::default()
        },
    )
    .unwrap();
    let (t1, v1) = ds.split(0.2, 3);
    let (t2, v2) = ds.split(0.2, 3);
    assert_eq!((t1.count(), v1.count()), (40, 10));
    assert_eq!((&t1, &v1), (&t2, &v2));
    assert!(v1.q.iter().all(|q| !t1.q.contains(q)));
}

/// Δt from the file or from the caller (--dt, ?dt=): either alone works, both must agree.
#[test]
fn dt_from_the_file_or_the_caller_never_contradicting() {
    let without = GOOD.replace(r#""dt":0.01,"#, "");
    let ds = Dataset::from_json(&without, Some(0.02)).unwrap();
    assert_eq!(ds.dt, 0.02);
    assert_eq!(Dataset::from_json(GOOD, Some(0.01)).unwrap().dt, 0.01);
    let err = Dataset::from_json(GOOD, Some(0.02)).unwrap_err();
    let msg = err.to_string();
    assert_eq!(field_of(err), "dt");
    assert!(msg.contains("0.01") && msg.contains("0.02"), "{msg}");
    let msg = Dataset::from_json(&without, None).unwrap_err().to_string();
    assert!(msg.contains("--dt"), "the error says how to give it: {msg}");
}

/// The trajectory form is a dataset file too (`graybox train --data`), with --dt when it has
/// no dt of its own.
#[test]
fn trajectory_files_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("traj.json");
    std::fs::write(
        &path,
        r#"{"trajectories": [{"q": [[0.0], [0.1], [0.2]], "qdot": [[1.0], [1.0], [1.1]], "u": [[0.5], [0.4]]}]}"#,
    )
    .unwrap();
    let ds = Dataset::load(&path, Some(0.1)).unwrap();
    assert_eq!((ds.count(), ds.nq, ds.nv, ds.m, ds.dt), (2, 1, 1, 1, 0.1));
    assert_eq!(ds.q_next, [0.1, 0.2]);
    assert_eq!(ds.qdot_next, [1.0, 1.1]);
    let err = Dataset::load(&path, None).unwrap_err();
    assert_eq!(field_of(err), "dt");
}

/// The sanity checks stay silent on the paper's data (every template, default sampling) and
/// fire on the same data in degrees (README, "Dataset warnings").
#[test]
fn paper_data_raises_no_warnings_and_degrees_do() {
    for t in [
        Template::DoublePendulum,
        Template::Pendulum,
        Template::Cartpole,
    ] {
        let ds = simulate(&t, t.defaults(), &SimConfig::default()).unwrap();
        assert_eq!(ds.warnings(), [], "{t:?}");
        let mut deg = ds.clone();
        // The angles (all of q for the pendulums, θ for the cart-pole) to degrees.
        let angles: Vec<usize> = match t {
            Template::Cartpole => vec![1],
            _ => (0..ds.nq).collect(),
        };
        for a in [
            &mut deg.q,
            &mut deg.qdot,
            &mut deg.q_next,
            &mut deg.qdot_next,
        ] {
            for (k, v) in a.iter_mut().enumerate() {
                if angles.contains(&(k % ds.nq)) {
                    *v = v.to_degrees();
                }
            }
        }
        let codes: Vec<String> = deg.warnings().into_iter().map(|w| w.code).collect();
        assert!(
            codes.contains(&"coordinate_span".to_string()),
            "{t:?}: {codes:?}"
        );
    }
}

/// The README's trajectory recipes (`examples/python/train_swings.py`'s swings, and the
/// multi-step section's `simulate --trajectories 40 --steps 200 --qdot-range 2 --u-std 30`)
/// wind a few turns, in radians: no coordinate_span warning, whatever the seed (the check
/// above keeps firing on degrees).
#[test]
fn winding_trajectories_of_the_readme_recipes_raise_no_span_warning() {
    let dir = tempfile::tempdir().unwrap();
    let recipes: [&[&str]; 2] = [
        &["--trajectories", "20", "--steps", "200", "--u-std", "30"],
        &[
            "--trajectories",
            "40",
            "--steps",
            "200",
            "--qdot-range",
            "2",
            "--u-std",
            "30",
        ],
    ];
    for (r, flags) in recipes.iter().enumerate() {
        for seed in 0..6 {
            let out = dir.path().join(format!("r{r}-{seed}.json"));
            let seed = seed.to_string();
            let args = [
                "simulate",
                "--system",
                "double_pendulum",
                "--seed",
                &seed,
                "--out",
            ];
            let done = std::process::Command::new(env!("CARGO_BIN_EXE_graybox"))
                .args(args)
                .arg(&out)
                .args(*flags)
                .output()
                .unwrap();
            assert!(done.status.success(), "{done:?}");
            let ds = Dataset::load(&out, None).unwrap();
            let spans: Vec<_> = (ds.warnings().into_iter())
                .filter(|w| w.code == "coordinate_span")
                .map(|w| w.message)
                .collect();
            assert!(spans.is_empty(), "{flags:?} seed {seed}: {spans:?}");
        }
    }
}

/// Transitions of their own Δt: `"dt"` as one step per transition, or each trajectory's
/// times `"t"`; the dataset's Δt their median; both forms written back as they came.
#[test]
fn each_transition_may_carry_its_own_step() {
    let each = GOOD.replace(r#""dt":0.01"#, r#""dt":[0.01,0.012]"#);
    let d = Dataset::from_json(&each, None).unwrap();
    assert_eq!(d.steps, Some(vec![0.01, 0.012]));
    assert_eq!((d.dt, d.step(1)), (0.011, 0.012));
    assert_eq!(Dataset::from_json(&d.to_json(), None).unwrap(), d);
    // Steps all equal are one dt.
    let same = GOOD.replace(r#""dt":0.01"#, r#""dt":[0.01,0.01]"#);
    assert_eq!(Dataset::from_json(&same, None).unwrap().steps, None);

    let timed = r#"{"trajectories":[
        {"t":[0,0.01,0.021],"q":[[0],[1],[2]],"qdot":[[0],[1],[2]],"u":[[0],[0]]},
        {"t":[5,5.009],"q":[[0],[1]],"qdot":[[0],[1]],"u":[[0]]}]}"#;
    let d = Dataset::from_json(timed, None).unwrap();
    let steps = d.steps.clone().unwrap();
    let want = [0.01, 0.011, 0.009];
    assert!(
        steps.iter().zip(want).all(|(a, b)| (a - b).abs() < 1e-12),
        "{steps:?}"
    );
    assert_eq!(d.trajectories, Some(vec![2, 1]));
    let back = Dataset::from_json(&d.to_json(), None).unwrap();
    let close = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-12);
    assert!(close(back.steps.as_ref().unwrap(), &steps) && back.q == d.q);
    // A split keeps each row's step.
    let (train, val) = d.split(0.34, 1);
    for part in [&train, &val] {
        let s = part.steps.as_ref().unwrap();
        assert!(
            s.iter().all(|v| want.iter().any(|w| (v - w).abs() < 1e-12)),
            "{s:?}"
        );
    }
}

#[test]
fn bad_steps_name_the_field() {
    let bad = |text: String, dt: Option<f64>| field_of(Dataset::from_json(&text, dt).unwrap_err());
    let with = |dt: &str| GOOD.replace(r#""dt":0.01"#, &format!(r#""dt":{dt}"#));
    assert_eq!(
        bad(with("[0.01]"), None),
        "dt",
        "one step for two transitions"
    );
    assert_eq!(bad(with("[]"), None), "dt");
    assert_eq!(bad(with("[0.01,-1]"), None), "dt[1]");
    assert_eq!(bad(with("[0.01,\"x\"]"), None), "dt[1]");
    assert_eq!(bad(with("[0.01,0.01]"), Some(0.01)), "dt", "given twice");
    let trajectory = |t: &str| {
        format!(
            r#"{{"trajectories":[{{"t":{t},"q":[[0],[1],[2]],"qdot":[[0],[1],[2]],"u":[[0],[0]]}}]}}"#
        )
    };
    assert_eq!(bad(trajectory("[0,0.01,0.01]"), None), "trajectories[0].t");
    assert_eq!(bad(trajectory("[0,0.01]"), None), "trajectories[0].t");
    let half = r#"{"dt":0.01,"trajectories":[
        {"t":[0,0.01],"q":[[0],[1]],"qdot":[[0],[1]],"u":[[0]]},
        {"q":[[0],[1]],"qdot":[[0],[1]],"u":[[0]]}]}"#;
    assert_eq!(bad(half.into(), None), "trajectories[1].t");
}
