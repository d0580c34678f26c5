use super::*;

fn atom(c: [f32; 3], chain: u32) -> Sphere {
    Sphere {
        center: c,
        radius: 1.0,
        color: [255; 4],
        region: [chain, 0, 0, 0],
    }
}

#[test]
fn a_known_quarter_turn() {
    // 90 degrees about z: (1, 0, 0) -> (0, 1, 0), then +t
    let q = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2);
    let r = rigid_from(q, [10.0, 0.0, 0.0]);
    let p = apply_rigid(&r, [1.0, 0.0, 0.0]);
    assert!((p[0] - 10.0).abs() < 1e-6 && (p[1] - 1.0).abs() < 1e-6 && p[2].abs() < 1e-6);
    // the same operator as a matrix is recognised as rigid, same result
    let m = [
        [0.0, -1.0, 0.0, 10.0],
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    let r2 = rigid_of(&m).unwrap();
    let p2 = apply_rigid(&r2, [1.0, 0.0, 0.0]);
    assert!((p2[0] - 10.0).abs() < 1e-6 && (p2[1] - 1.0).abs() < 1e-6);
    // a sheared matrix is not rigid
    let mut s = m;
    s[0][1] = -1.001;
    assert!(rigid_of(&s).is_none());
    let a = s.map(|row| row.map(|v| v as f32));
    assert_eq!(apply_affine(&a, [0.0, 1.0, 0.0]), [10.0 - 1.001, 0.0, 0.0]);
}

fn two_molecules() -> InstancedBuilder {
    let mut b = InstancedBuilder::default();
    let n1 = b.node(&["virion", "spike"]);
    let n2 = b.node(&["virion", "membrane"]);
    let m1 = b.molecule(
        "S",
        n1,
        vec![atom([1.0, 0.0, 0.0], 0), atom([2.0, 0.0, 0.0], 1)],
    );
    let m2 = b.molecule("M", n2, vec![atom([0.0, 0.0, 1.0], 0)]);
    let e = b.molecule("empty", n2, vec![]);
    let id = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    let mut shift = id;
    shift[0][3] = 100.0;
    b.instance_matrix("t", m1, id).unwrap();
    b.instance_matrix("t", e, id).unwrap();
    b.instance_matrix("t", m2, shift).unwrap();
    b.instance_matrix("t", m1, shift).unwrap();
    b
}

#[test]
fn expanded_order_regions_and_levels() {
    let s = two_molecules().finish("t").unwrap();
    let inst = s.instancing.as_ref().unwrap();
    // the empty molecule's instance is dropped
    assert_eq!(inst.instances(), 3);
    assert_eq!(s.represented(), 5);
    assert!(matches!(inst.transforms, Transforms::Rigid(_)));
    // depth 1 (virion) separates nothing; depth 2, molecule, chain do
    assert_eq!(
        inst.levels,
        vec![LevelKind::Tree(2), LevelKind::Molecule, LevelKind::Chain]
    );
    let e = s.expand().unwrap();
    let xs: Vec<f32> = e.spheres.iter().map(|s| s.center[0]).collect();
    assert_eq!(xs, vec![1.0, 2.0, 100.0, 101.0, 102.0]);
    let mol: Vec<u32> = e.spheres.iter().map(|s| s.region[1]).collect();
    assert_eq!(mol, vec![0, 0, 1, 2, 2]);
    let chain: Vec<u32> = e.spheres.iter().map(|s| s.region[2]).collect();
    assert_eq!(chain, vec![0, 1, 2, 4, 5]);
    assert_ne!(e.spheres[0].region[0], e.spheres[2].region[0]);
    assert_eq!(e.spheres[0].region[0], e.spheres[3].region[0]);
    for i in 0..5 {
        assert_eq!(s.sphere(i).unwrap(), e.spheres[i as usize]);
    }
    assert_eq!(s.sphere(5), None);
    // every level separates something in the expanded scene too
    for l in 0..3 {
        let first = e.spheres[0].region[l];
        assert!(e.spheres.iter().any(|s| s.region[l] != first), "level {l}");
    }
}

#[test]
fn single_chain_molecules_have_no_chain_level() {
    let mut b = InstancedBuilder::default();
    let n = b.node(&["beads"]);
    let m = b.molecule("bead", n, vec![atom([0.0; 3], 0), atom([1.0, 0.0, 0.0], 0)]);
    for k in 0..3 {
        b.instance_quat("t", m, DQuat::IDENTITY, [k as f64 * 10.0, 0.0, 0.0])
            .unwrap();
    }
    let s = b.finish("t").unwrap();
    assert_eq!(
        s.instancing.as_ref().unwrap().levels,
        vec![LevelKind::Molecule]
    );
    assert_eq!(s.level_names, vec!["molecule".to_string()]);
    assert!(b_zero_rotation_is_refused());
}

fn b_zero_rotation_is_refused() -> bool {
    let mut b = InstancedBuilder::default();
    b.instance_quat("t", 0, DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), [0.0; 3])
        .is_err()
}

#[test]
fn non_rigid_operators_stay_affine() {
    let mut b = two_molecules();
    let mut shear = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    shear[0][1] = 0.002;
    let m = 0;
    b.instance_matrix("t", m, shear).unwrap();
    let s = b.finish("t").unwrap();
    let inst = s.instancing.as_ref().unwrap();
    assert!(matches!(inst.transforms, Transforms::Affine(_)));
    assert_eq!(inst.transforms.bytes_per_instance(), 48);
    // the last instance: x' = x + 0.002 y (as stored)
    let e = s.expand().unwrap();
    assert_eq!(e.spheres.last().unwrap().center, [2.0, 0.0, 0.0]);
}

#[test]
fn far_instances_are_refused() {
    let mut b = InstancedBuilder::default();
    let m = b.molecule("a", 0, vec![atom([0.0; 3], 0)]);
    b.instance_quat("t", m, DQuat::IDENTITY, [1e16, 0.0, 0.0])
        .unwrap();
    let e = b.finish("far").unwrap_err();
    assert!(e.to_string().contains("outside"), "{e}");
    // the first far sphere is named by its expanded index, past instances
    // shown inside by their hulls and one near the limit that is scanned
    let mut b = InstancedBuilder::default();
    let m = b.molecule(
        "a",
        0,
        vec![
            atom([0.0; 3], 0),
            atom([1.0, 0.0, 0.0], 0),
            atom([2.0, 0.0, 0.0], 0),
        ],
    );
    for x in [0.0, 5e14, 9.999e14, 2e15, 3e15] {
        b.instance_quat("t", m, DQuat::IDENTITY, [x, 0.0, 0.0])
            .unwrap();
    }
    let e = b.finish("far").unwrap_err().to_string();
    assert!(e.contains("sphere 9 lands"), "{e}");
    let mut b = InstancedBuilder::default();
    let m = b.molecule(
        "a",
        0,
        vec![atom([0.0; 3], 0), atom([f32::NAN, 0.0, 0.0], 0)],
    );
    b.instance_quat("t", m, DQuat::IDENTITY, [0.0; 3]).unwrap();
    let e = b.finish("nan").unwrap_err().to_string();
    assert!(e.contains("sphere 1 lands"), "{e}");
}

#[test]
fn a_selection_that_names_nothing_is_told_the_names() {
    let s = two_molecules().finish("t").unwrap();
    let inst = s.instancing.as_ref().unwrap();
    let labels: Vec<&str> = inst.molecules.iter().map(|m| m.label.as_str()).collect();
    let all = inst.names_hint(100);
    // every molecule type, and no count when all are shown
    assert!(
        all.starts_with(&format!("molecule types: {};", labels.join(", "))),
        "{all}"
    );
    assert!(!all.contains("in all"), "{all}");
    // past `most`: the first ones, then how many there are
    let one = inst.names_hint(1);
    assert!(
        one.starts_with(&format!(
            "molecule types: {}, ... ({} in all);",
            labels[0],
            labels.len()
        )),
        "{one}"
    );
    assert!(one.contains("in all)"), "{one}");
}
