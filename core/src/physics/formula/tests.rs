use super::*;
use crate::physics::dual::Dual;

fn names() -> Names {
    Names {
        coordinates: vec!["x".into(), "theta".into()],
        inputs: vec!["f".into()],
        parameters: vec!["mp".into(), "l".into(), "g".into()],
    }
}

fn value(text: &str) -> f64 {
    let e = parse(text, &names()).unwrap_or_else(|e| panic!("{text}: {e}"));
    // x = 0.3, θ = −1.2, ẋ = 0.7, θ̇ = 2.5, f = 4, mp = 0.5, l = 0.6, g = 9.81
    let sym = |s: Symbol| match s {
        Symbol::Q(i) => [0.3, -1.2][i],
        Symbol::QDot(i) => [0.7, 2.5][i],
        Symbol::U(_) => 4.0,
        Symbol::Param(i) => [0.5, 0.6, 9.81][i],
    };
    e.eval(&sym, &0.0)
}

#[test]
fn precedence_and_associativity_follow_the_grammar() {
    // Each against the same formula written in Rust.
    assert_eq!(value("1 + 2 * 3"), 7.0);
    assert_eq!(value("2 ^ 3 ^ 2"), 512.0);
    assert_eq!(value("-x^2"), -(0.3f64 * 0.3));
    assert_eq!(value("(-x)^2"), 0.3f64 * 0.3);
    assert_eq!(value("8 / 4 / 2"), 1.0);
    assert_eq!(value("10 - 4 - 3"), 3.0);
    assert_eq!(value("2 * -3"), -6.0);
    assert_eq!(value("x^-2"), 1.0 / (0.3f64 * 0.3));
    assert_eq!(value("1.5e2 + .5 + 2E-1"), 150.7);
}

#[test]
fn names_functions_and_constants_evaluate_like_rust() {
    let (x, th, xd, thd, f, mp, l, g) = (0.3f64, -1.2f64, 0.7, 2.5, 4.0, 0.5, 0.6, 9.81);
    let close = |a: f64, b: f64| assert!((a - b).abs() <= 1e-15 * b.abs().max(1.0), "{a} vs {b}");
    close(value("mp*l*cos(theta)"), mp * l * th.cos());
    close(value("-mp*g*l*cos(theta)"), -mp * g * l * th.cos());
    close(value("f + -0.1*x_dot + theta_dot"), f - 0.1 * xd + thd);
    close(
        value("tan(x) + exp(x) + log(l) + sqrt(g)"),
        x.tan() + x.exp() + l.ln() + g.sqrt(),
    );
    close(
        value("tanh(x) + sinh(x) + cosh(x)"),
        x.tanh() + x.sinh() + x.cosh(),
    );
    close(value("atan2(theta, x)"), th.atan2(x));
    close(value("l ^ 1.5"), l.powf(1.5));
    close(value("pi"), std::f64::consts::PI);
}

#[test]
fn errors_name_what_and_where() {
    let err = |t: &str| parse(t, &names()).unwrap_err();
    let e = err("mp * foo");
    assert_eq!(e.offset, 5);
    assert!(
        e.message.contains("unknown name 'foo'") && e.message.contains("theta_dot"),
        "{e}"
    );
    let e = err("sin(x) + cosine(x)");
    assert_eq!(
        (e.offset, e.message.contains("unknown function 'cosine'")),
        (9, true),
        "{e}"
    );
    let e = err("mp * (l + 1");
    assert_eq!(e.offset, 11);
    assert!(e.message.contains("offset 5"), "{e}");
    assert_eq!(err("mp +* l").offset, 4);
    assert_eq!(err("mp l").offset, 3);
    assert_eq!(err("x)").offset, 1);
    assert_eq!(err("x # 2").offset, 2);
    assert_eq!(err("").offset, 0);
    assert_eq!(err("   ").offset, 3);
    let e = err("atan2(x)");
    assert!(e.message.contains("takes 2"), "{e}");
    let e = err("sin + 1");
    assert!(e.message.contains("is a function"), "{e}");
    // Offsets count characters, not bytes.
    assert_eq!(err("θ + 1").offset, 0);
    assert_eq!(err("x + θ").offset, 4);
}

#[test]
fn symbols_are_reported_with_their_offsets() {
    let e = parse("mp*l*cos(theta) + theta_dot*f", &names()).unwrap();
    assert_eq!(
        e.symbols(),
        vec![
            (Symbol::Param(0), 0),
            (Symbol::Param(1), 3),
            (Symbol::Q(1), 9),
            (Symbol::QDot(1), 18),
            (Symbol::U(0), 28)
        ]
    );
}

/// Dual numbers differentiate every operator and function: against central differences.
#[test]
fn dual_derivatives_match_finite_differences() {
    let names = Names {
        coordinates: vec!["a".into(), "b".into()],
        ..Names::default()
    };
    let texts = [
        "a^3 - 2*a*b + b^-2",
        "sin(a)*cos(b) + tan(a/3)",
        "exp(a - b) + log(b) + sqrt(b)",
        "tanh(a) + sinh(b) + cosh(a*b)",
        "atan2(a, b) + b^1.5 + 1/(a + 2)",
    ];
    let at = [0.7, 1.3];
    for t in texts {
        let e = parse(t, &names).unwrap();
        let f = |a: f64, b: f64| {
            e.eval(
                &|s| match s {
                    Symbol::Q(0) => a,
                    _ => b,
                },
                &0.0,
            )
        };
        let d = e.eval(
            &|s| match s {
                Symbol::Q(i) => Dual::variable(at[i], i, 2, 1.0),
                _ => unreachable!(),
            },
            &Dual::<f64>::constant(0.0),
        );
        assert!((d.v - f(at[0], at[1])).abs() < 1e-14, "{t}");
        // Central differences: error ~ h² f''' ≈ 1e-10 at h = 1e-5; rounding ~ 1e-16/h.
        let h = 1e-5;
        let fd = [
            (f(at[0] + h, at[1]) - f(at[0] - h, at[1])) / (2.0 * h),
            (f(at[0], at[1] + h) - f(at[0], at[1] - h)) / (2.0 * h),
        ];
        for (k, fd) in fd.iter().enumerate() {
            let ad = d.tangent(k).copied().unwrap_or(0.0);
            assert!(
                (ad - fd).abs() < 1e-8 * fd.abs().max(1.0),
                "{t} ∂{k}: {ad} vs {fd}"
            );
        }
    }
}
