//! Issue 72: collocation started from a caller's far-off initial states (x_init of 1e6) was
//! refused blaming R ("R + BᵀSB lost positive definiteness"), and from 1e150 or 1e300
//! blaming x0. The refusal names x_init, and says how to do better.

use graybox::control::linalg::Mat;
use graybox::control::make_plan;
use graybox::control::plan::{Method, PlanRequest};
use graybox::error::Error;

use super::common::plans::{swing_up, true_double_pendulum};

#[test]
fn far_off_initial_states_are_named_as_the_fault() {
    let eval = true_double_pendulum();
    let horizon = 21;
    for scale in [1e6, 1e150, 1e300] {
        let req = PlanRequest {
            method: Method::Dircol,
            x_init: Some(Mat::new(horizon + 1, 4, vec![scale; 4 * (horizon + 1)])),
            ..swing_up(horizon)
        };
        match make_plan(&eval, &req, &|| false) {
            Err(Error::Invalid { field, message }) => {
                assert_eq!(field, "x_init", "{scale:e}: {message}");
                assert!(message.contains("leave x_init out"), "{message}");
                assert!(!message.contains("R + BᵀSB lost"), "{message}");
            }
            other => panic!(
                "{scale:e}: expected a refusal, got {:?}",
                other.map(|p| p.cost)
            ),
        }
    }
}

/// The same far-off states given as the nominal of gains are that nominal's fault, not R's
/// (R was checked positive definite before any step).
#[test]
fn gains_along_a_far_off_nominal_name_the_nominal() {
    let eval = true_double_pendulum();
    let t = 20;
    let xbar = vec![1e6; 4 * (t + 1)];
    let ubar = vec![0.0; 2 * t];
    let eye = |d: usize, s: f64| Mat::diag(&vec![s; d]);
    match eval.tvlqr(&xbar, &ubar, &eye(4, 1.0), &eye(2, 1e-4), &eye(4, 1000.0)) {
        Err(Error::Invalid { field, message }) => {
            assert_eq!(field, "x_bar", "{message}");
            assert!(
                message.contains("R itself is positive definite"),
                "{message}"
            );
        }
        other => panic!("expected a refusal, got {:?}", other.map(|g| g.k.len())),
    }
}
