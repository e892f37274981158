//! The URDF export's own checks: elements found as the reader finds them, read-back
//! refusals, comments kept well-formed.

use super::*;

/// Names are the `name` attributes, unescaped; markup in comments and attribute values
/// is not an element.
#[test]
fn elements_skip_comments_and_read_names() {
    let doc = "<?xml version=\"1.0\"?>\n<robot name=\"r\"><!-- <link name=\"no\"/> -->\
               <link name='a' ><visual/></link><joint name=\"j\" type=\"fixed\"></joint>\
               <link foo=\" name='l1'\" name=\"decoy\"/><link name=\"a&amp;b\"/>\
               <link myname=\"x\"/></robot>";
    let e = elements(doc).unwrap();
    let names: Vec<(&str, Option<&str>, usize)> = e
        .iter()
        .map(|e| (e.tag.as_str(), e.name.as_deref(), e.depth))
        .collect();
    assert_eq!(
        names,
        [
            ("robot", Some("r"), 0),
            ("link", Some("a"), 1),
            ("visual", None, 2),
            ("joint", Some("j"), 1),
            ("link", Some("decoy"), 1),
            ("link", Some("a&b"), 1),
            ("link", None, 1)
        ]
    );
}

/// Values claimed for a link the document does not have them on, or a document that is
/// not XML, are refused as an internal error.
#[test]
fn a_document_that_does_not_read_back_is_refused() {
    let doc = r#"<robot name="r"><link name="base"/>
        <joint name="j" type="continuous"><parent link="base"/><child link="l"/>
        <axis xyz="0 0 1"/></joint>
        <link name="l"><inertial><mass value="1"/>
        <inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial></link>
        </robot>"#;
    let t = UrdfTemplate::from_urdf(doc).unwrap();
    let physical: Vec<f64> = t.params().iter().map(|p| p.default).collect();
    let good = export(&t, &physical).unwrap();
    let none = HashMap::new();
    let heavier = Written {
        mass: 2.0,
        ..Written::MERGED
    };
    let links = HashMap::from([("l".to_string(), heavier)]);
    let refused = |r: Result<()>, what: &str| match r {
        Err(Error::Internal(m)) => assert!(m.contains(what), "{m}"),
        other => panic!("expected an internal error, got {other:?}"),
    };
    refused(
        check_read_back(&t, doc, &links, &HashMap::new()),
        "link 'l'",
    );
    let joints = HashMap::from([("j".to_string(), ((0.5, 0.0), None))]);
    refused(check_read_back(&t, &good, &none, &joints), "joint 'j'");
    let broken = good.replace("</robot>", "</link></robot>");
    refused(
        check_read_back(&t, &broken, &none, &HashMap::new()),
        "not XML",
    );
}

#[test]
fn comments_never_hold_two_hyphens() {
    assert_eq!(in_comment("a--b---c-"), "a- -b- - -c-");
}
