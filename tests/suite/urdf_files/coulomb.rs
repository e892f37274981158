//! Issue 28, item 6: the Coulomb term's ε is an option of the URDF document (`coulomb_eps`,
//! default 0.01), and a template whose forces are too stiff for the step is warned about, with
//! the ε that would not be.

use std::process::Command;
use std::sync::Arc;

use graybox::error::Error;
use graybox::model::file::ModelFile;
use graybox::physics::integrator::Integrator;
use graybox::physics::stiffness::{limit, stiffness, velocity_stiffness, warning};
use graybox::physics::templates::Template;
use graybox::physics::urdf::UrdfTemplate;
use serde_json::{Value, json};

use super::fixture;

fn doc(urdf: &str, eps: Option<f64>) -> Value {
    let mut d = json!({"kind": "urdf", "urdf": urdf});
    if let Some(e) = eps {
        d["coulomb_eps"] = json!(e);
    }
    d
}

fn eps_of(t: &Template) -> f64 {
    match t {
        Template::Urdf(u) => u.doc.coulomb_eps,
        _ => unreachable!(),
    }
}

/// arm4 with every joint's `<dynamics>` made `damping="d" friction="f"` (the fixed joint's
/// too, which nothing reads).
fn arm4_with_friction(d: f64, f: f64) -> String {
    let text = fixture("arm4")
        .replace(r#"<dynamics damping="0.1" friction="0.05"/>"#, "")
        .replace(r#"<dynamics damping="0.5"/>"#, "");
    assert!(!text.contains("<dynamics"));
    text.replace(
        "</joint>",
        &format!(r#"<dynamics damping="{d}" friction="{f}"/></joint>"#),
    )
}

/// The option is read, written back only when it is not the default, refused out of range
/// naming the field, and a model file without it (every file before it) means ε = 0.01.
#[test]
fn coulomb_eps_round_trips_and_defaults_to_the_old_value() {
    let urdf = fixture("double_pendulum");
    let t = Template::from_document(&doc(&urdf, Some(0.5))).unwrap();
    assert_eq!(eps_of(&t), 0.5);
    let written = serde_json::to_value(&t).unwrap();
    assert_eq!(written["coulomb_eps"], json!(0.5));
    assert_eq!(Template::from_document(&written).unwrap(), t);

    let old = Template::from_document(&doc(&urdf, None)).unwrap();
    assert_eq!(eps_of(&old), 0.01);
    assert!(
        serde_json::to_value(&old)
            .unwrap()
            .get("coulomb_eps")
            .is_none()
    );
    for bad in [0.0, -0.1, 1e-9, 2e6] {
        match Template::from_document(&doc(&urdf, Some(bad))) {
            Err(Error::Unprocessable { field, .. }) => assert_eq!(field, "coulomb_eps"),
            other => panic!("{bad}: expected a 422, got {other:?}"),
        }
    }

    for (t, eps) in [(old, 0.01), (t, 0.5)] {
        let file = ModelFile::from_template(&t, &t.defaults(), 0.01, Integrator::Rk4).unwrap();
        let bytes = file.to_bytes().unwrap();
        let text = String::from_utf8(bytes.clone()).unwrap();
        assert_eq!(text.contains("coulomb_eps"), eps != 0.01);
        let back = ModelFile::from_bytes(&bytes).unwrap();
        assert_eq!(eps_of(back.config.template().unwrap()), eps);
    }
}

/// F = u − d q̇ − f tanh(q̇/ε) per joint, by hand, at one state for two ε.
#[test]
fn forces_follow_the_formula_with_the_documents_eps() {
    let urdf = fixture("double_pendulum").replace(
        r#"<dynamics damping="0.5"/>"#,
        r#"<dynamics damping="0.5" friction="0.7"/>"#,
    );
    let (qd, u) = ([0.3, -0.05], [1.5, -2.0]);
    for eps in [0.01, 0.2] {
        let t = Template::from_document(&doc(&urdf, Some(eps))).unwrap();
        let f = t.forces(&t.defaults(), &[0.4, -1.0], &qd, &u);
        for i in 0..2 {
            let want = u[i] - 0.5 * qd[i] - 0.7 * (qd[i] / eps).tanh();
            assert!((f[i] - want).abs() <= 1e-15, "ε {eps}: {f:?}");
        }
        // −∂F/∂q̇ at rest is d + f/ε on the diagonal, nothing off it.
        let d = velocity_stiffness(&t, &t.defaults(), &[0.4, -1.0]);
        assert_eq!(d[0][1], 0.0);
        assert!(
            (d[1][1] - (0.5 + 0.7 / eps)).abs() < 1e-12 * d[1][1],
            "{d:?}"
        );
    }
}

/// λ_max of D v = λ M v against independent computations: for the 2-DoF pendulum the larger
/// root of det(D − λM) = 0; for arm4 (4 DoF) power iteration on M⁻¹D solved by Gaussian
/// elimination (10⁴ iterations; the two largest rates differ by far more than needed).
/// Both are f64 on the same M and D, so 1e-9 is rounding plus the iteration's tail.
#[test]
fn the_time_constant_is_the_generalized_eigenvalue() {
    let urdf = fixture("double_pendulum").replace(
        r#"<dynamics damping="0.5"/>"#,
        r#"<dynamics damping="0.5" friction="0.7"/>"#,
    );
    let t = Template::from_document(&doc(&urdf, None)).unwrap();
    let p = t.defaults();
    let (m, d) = (
        t.mass(&p, &[0.0, 0.0]),
        velocity_stiffness(&t, &p, &[0.0, 0.0]),
    );
    let a = m[0][0] * m[1][1] - m[0][1] * m[1][0];
    let b = -(d[0][0] * m[1][1] + d[1][1] * m[0][0]);
    let c = d[0][0] * d[1][1];
    let lambda = (-b + (b * b - 4.0 * a * c).sqrt()) / (2.0 * a);
    let tau = stiffness(&t, &p, 0.01, 2.0, &[]).tau;
    assert!(
        (tau * lambda - 1.0).abs() < 1e-9,
        "τ {tau} vs 1/λ {}",
        1.0 / lambda
    );

    let t = Template::Urdf(Arc::new(
        UrdfTemplate::from_urdf(&arm4_with_friction(0.1, 1.0)).unwrap(),
    ));
    let p = t.defaults();
    // τ is the shortest over q = 0 and the configurations given.
    let q = [0.3, -0.7, 0.1, 1.2];
    let rate = |q: &[f64]| power_iteration(&t.mass(&p, q), &velocity_stiffness(&t, &p, q));
    let fastest = rate(&[0.0; 4]).max(rate(&q));
    let s = stiffness(&t, &p, 0.01, 2.0, &[q.to_vec()]);
    assert!(
        (s.tau * fastest - 1.0).abs() < 1e-9,
        "τ {} vs 1/λ {}",
        s.tau,
        1.0 / fastest
    );
    assert_eq!(t.coordinates()[s.coordinate], "wrist");
}

/// The dominant eigenvalue of M⁻¹D by power iteration.
fn power_iteration(m: &[Vec<f64>], d: &[Vec<f64>]) -> f64 {
    let n = m.len();
    let (mut v, mut lambda) = (vec![1.0; n], 0.0);
    for _ in 0..10_000 {
        let dv: Vec<f64> = (0..n)
            .map(|i| (0..n).map(|j| d[i][j] * v[j]).sum())
            .collect();
        let w = solve(m, &dv);
        lambda = w.iter().map(|x| x.abs()).fold(0.0, f64::max);
        v = w.iter().map(|x| x / lambda).collect();
    }
    lambda
}

/// Gaussian elimination with partial pivoting.
fn solve(m: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let mut a: Vec<Vec<f64>> = m
        .iter()
        .zip(b)
        .map(|(r, &bi)| [r.clone(), vec![bi]].concat())
        .collect();
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap();
        a.swap(c, p);
        let pivot = a[c].clone();
        for row in a.iter_mut().skip(c + 1) {
            let f = row[c] / pivot[c];
            for (x, p) in row.iter_mut().zip(&pivot).skip(c) {
                *x -= f * p;
            }
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        x[r] = (a[r][n] - (r + 1..n).map(|k| a[r][k] * x[k]).sum::<f64>()) / a[r][r];
    }
    x
}

/// arm4 with a Coulomb friction of 1 on every joint is far too stiff at Δt = 0.01 (its light
/// wrist), and the warning names the ε that is not: at that ε λ_max Δt is the integrator's
/// limit (no damping: the bound it comes from is then exact) and nothing is said, at 0.9 of it
/// the warning is back. Euler's limit is half RK4's, so it needs twice the ε. The paper's
/// double pendulum as URDF (10 kg rods, damping 0.5) is not stiff.
#[test]
fn the_warning_fires_when_the_step_is_past_the_integrators_limit() {
    let urdf = arm4_with_friction(0.0, 1.0);
    let t = Template::from_document(&doc(&urdf, None)).unwrap();
    let (p, dt) = (t.defaults(), 0.01);
    let says = warning(&t, &p, dt, Integrator::Rk4, &[]).expect("stiff");
    assert!(
        says.contains("'wrist'") && says.contains("coulomb_eps"),
        "{says}"
    );
    let mut cures = vec![];
    for integrator in [Integrator::Rk4, Integrator::Euler] {
        let k = limit(integrator);
        let eps = stiffness(&t, &p, dt, k, &[]).eps.expect("an ε cures it");
        let cured = Template::from_document(&doc(&urdf, Some(eps))).unwrap();
        let tau = stiffness(&cured, &p, dt, k, &[]).tau;
        assert!(
            (dt / tau - k).abs() < 1e-9 * k,
            "λΔt {} at ε {eps}",
            dt / tau
        );
        assert!(warning(&cured, &p, dt * (1.0 - 1e-6), integrator, &[]).is_none());
        let short = Template::from_document(&doc(&urdf, Some(0.9 * eps))).unwrap();
        assert!(warning(&short, &p, dt, integrator, &[]).is_some());
        cures.push(eps);
    }
    assert!((cures[1] / cures[0] - 2.0).abs() < 1e-9, "{cures:?}");

    let benign = Template::from_document(&doc(&fixture("double_pendulum"), None)).unwrap();
    assert!(warning(&benign, &benign.defaults(), dt, Integrator::Rk4, &[]).is_none());
}

fn graybox(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_graybox"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The CLI says so on stderr: `simulate`, `model`, `train` (as it starts, and in its report)
/// and `plan`, for the stiff document; nothing for the same robot at the recommended ε.
#[test]
fn the_cli_warns_on_stderr() {
    let dir = std::env::temp_dir().join(format!("graybox-coulomb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = |name: &str| dir.join(name).to_string_lossy().into_owned();
    let urdf = arm4_with_friction(0.0, 1.0);
    let t = Template::from_document(&doc(&urdf, None)).unwrap();
    let eps = stiffness(&t, &t.defaults(), 0.01, limit(Integrator::Rk4), &[])
        .eps
        .unwrap();
    for (name, eps, stiff) in [("stiff", None, true), ("smooth", Some(2.0 * eps), false)] {
        let template = path(&format!("{name}.json"));
        std::fs::write(&template, doc(&urdf, eps).to_string()).unwrap();
        let (data, model) = (
            path(&format!("{name}-d.json")),
            path(&format!("{name}.gbx")),
        );
        let (planned, trained) = (path("plan.json"), path("t.gbx"));
        let runs: [Vec<&str>; 4] = [
            vec![
                "simulate",
                "--template",
                &template,
                "--count",
                "64",
                "--q-range",
                "1",
                "--qdot-range",
                "2",
                "--u-std",
                "1",
                "--out",
                &data,
            ],
            vec![
                "model",
                "--template",
                &template,
                "--dt",
                "0.01",
                "--out",
                &model,
            ],
            vec![
                "plan",
                "--model",
                &model,
                "--x0",
                "0,0,0,0,0,0,0,0",
                "--goal",
                "0.1,0,0,0,0,0,0,0",
                "--horizon",
                "5",
                "--max-iterations",
                "0",
                "--out",
                &planned,
            ],
            vec![
                "train",
                "--data",
                &data,
                "--model",
                "W-B",
                "--template",
                &template,
                "--epochs",
                "1",
                "--threads",
                "1",
                "--out",
                &trained,
            ],
        ];
        for args in runs {
            let (ok, stderr) = graybox(&args);
            assert!(ok, "{args:?}: {stderr}");
            let warned = stderr.matches("too stiff for a step").count();
            // train says it as it starts and again in its report's warnings.
            let want = match (stiff, args[0]) {
                (false, _) => 0,
                (true, "train") => 2,
                (true, _) => 1,
            };
            assert_eq!(warned, want, "{args:?}: {stderr}");
        }
    }
}

/// The warning says where the setting goes with a line to copy: put inside `<robot>`, the
/// `<graybox coulomb_eps>` it quotes makes the same file steppable (as the document's field
/// does); a document and a file that disagree are refused naming the field.
#[test]
fn the_warnings_one_line_fix_in_the_urdf_file_cures_it() {
    let urdf = arm4_with_friction(0.0, 1.0);
    let t = Template::from_document(&doc(&urdf, None)).unwrap();
    let (p, dt) = (t.defaults(), 0.01);
    let says = warning(&t, &p, dt, Integrator::Rk4, &[]).expect("stiff");
    let start = says.find("<graybox ").expect(&says);
    let line = &says[start..start + says[start..].find("/>").unwrap() + 2];
    assert!(says.contains("inside <robot>"), "{says}");
    let fixed = urdf.replacen("</robot>", &format!("{line}</robot>"), 1);
    let cured = Template::from_document(&doc(&fixed, None)).unwrap();
    assert!(eps_of(&cured) > 0.01, "{line}");
    assert!(
        warning(&cured, &p, dt, Integrator::Rk4, &[]).is_none(),
        "{line}"
    );
    // The document may say the same, not something else.
    let same = Template::from_document(&doc(&fixed, Some(eps_of(&cured)))).unwrap();
    assert_eq!(eps_of(&same), eps_of(&cured));
    match Template::from_document(&doc(&fixed, Some(0.5))) {
        Err(Error::Unprocessable { field, message }) => {
            assert_eq!(field, "coulomb_eps");
            assert!(message.contains("<graybox coulomb_eps>"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    let zero = urdf.replacen("</robot>", r#"<graybox coulomb_eps="0"/></robot>"#, 1);
    assert!(Template::from_document(&doc(&zero, None)).is_err());
}
