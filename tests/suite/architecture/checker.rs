//! The checker of `architecture.rs` tried on lines and trees it must accept or refuse.

use super::*;

fn deps(file: &str, line: &str) -> Vec<String> {
    deps_of_line(&module_path(Path::new(file)), line)
        .into_iter()
        .map(String::from)
        .collect()
}

#[test]
fn sees_every_form_of_dependency() {
    assert_eq!(deps("model/mod.rs", "use crate::store::Store;"), ["store"]);
    assert_eq!(
        deps(
            "app/jobs.rs",
            "use crate::{cli, store::{JobRow, JobState}, model};"
        ),
        ["cli", "store", "model"]
    );
    assert_eq!(
        deps(
            "api/rest/jobs.rs",
            "    last_state: Option<crate::store::JobRow>,"
        ),
        ["store"]
    );
    // `super::` inside a layer stays in it; climbing out of it names the target.
    assert!(deps("app/jobs.rs", "use super::App;").is_empty());
    assert_eq!(deps("app/mod.rs", "use super::store::Store;"), ["store"]);
    assert_eq!(
        deps(
            "api/rest/jobs.rs",
            "use super::super::super::worker::run_worker;"
        ),
        ["worker"]
    );
    assert_eq!(
        deps("sim.rs", "use super::{cli, model::Model};"),
        ["cli", "model"]
    );
    // Not dependencies: comments, `$crate::` and other crates' `…crate::`.
    assert!(deps("model/mod.rs", "// see crate::store").is_empty());
    assert!(deps("model/mod.rs", "$crate::model::x!()").is_empty());
    assert!(deps("model/mod.rs", "use my_crate::store;").is_empty());
}

#[test]
fn reports_file_line_and_layer() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("model");
    std::fs::create_dir(&model).unwrap();
    std::fs::write(
        model.join("mod.rs"),
        "//! math\nuse crate::error::Result;\nfn f() -> crate::app::App { todo!() }\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("cli.rs"), "use crate::store::Store;\n").unwrap();
    let v = violations(dir.path());
    assert_eq!(v.len(), 1, "{v:?}");
    assert!(
        v[0].starts_with("src/model/mod.rs:3: `model` must not import `app`"),
        "{v:?}"
    );
}

#[test]
fn physics_may_import_only_error_rng_and_names() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("physics")).unwrap();
    std::fs::write(
        dir.path().join("physics/mod.rs"),
        "use crate::error::Result;\nuse crate::{names, rng::Rng};\nuse crate::physics::x;\n\
         use crate::records::Job;\nuse crate::backend::Device;\n",
    )
    .unwrap();
    let v = violations(dir.path());
    assert_eq!(v.len(), 2, "{v:?}");
    assert!(v[0].starts_with("src/physics/mod.rs:4: `physics` must not import `records`"));
    assert!(v[1].starts_with("src/physics/mod.rs:5: `physics` must not import `backend`"));
}

#[test]
fn multibody_may_not_import_a_producer_or_the_assembly() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("physics/multibody/spatial")).unwrap();
    std::fs::write(
        dir.path().join("physics/multibody/mod.rs"),
        "use crate::physics::scalar::Scalar;\nuse crate::physics::{dual::Dual, urdf};\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("physics/multibody/spatial/raw.rs"),
        "use super::super::super::templates::Template;\nuse super::super::data::Data;\n",
    )
    .unwrap();
    let v = violations(dir.path());
    assert_eq!(v.len(), 2, "{v:?}");
    assert!(v[0].starts_with(
        "src/physics/multibody/mod.rs:2: `physics::multibody` must not import `physics::urdf`"
    ));
    assert!(v[1].starts_with(
        "src/physics/multibody/spatial/raw.rs:1: `physics::multibody` must not import \
         `physics::templates`"
    ));
}
