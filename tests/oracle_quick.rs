use tspace_tangent::{MeshInput, Options, UvOrigin, generate};
use tspace_testkit::shapes;
use tspace_testkit::*;

fn compare(
    name: &str,
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    uvs: &[[f32; 2]],
    indices: &[u32],
) {
    let reference = reference_tangents(positions, normals, uvs, indices);
    let input = MeshInput {
        positions,
        normals: Some(normals),
        uvs: Some(uvs),
        indices: Some(indices),
    };
    for parallel in [false, true] {
        let options = Options {
            uv_origin: UvOrigin::BottomLeft,
            parallel,
            ..Options::default()
        };
        let ours = generate(&input, &options).unwrap();
        let mut worst = 0.0f64;
        let mut bad = 0;
        let mut exact = 0;
        for (c, (r, o)) in reference
            .iter()
            .zip(&ours.corner_tangents(input.indices))
            .enumerate()
        {
            let n = normals[indices[c] as usize];
            if !reference_is_valid(*r, n) {
                continue;
            }
            let r = r.unwrap();
            let a = angle_degrees([r[0], r[1], r[2]], [o[0], o[1], o[2]]);
            if r == *o {
                exact += 1;
            }
            if a > 0.01 || r[3] != o[3] {
                bad += 1;
                if bad < 5 {
                    eprintln!("{name}: corner {c} ref {r:?} ours {o:?} angle {a}");
                }
            }
            worst = worst.max(a);
        }
        eprintln!(
            "{name} parallel={parallel}: {} corners, {exact} bit-exact, {bad} mismatched, worst {worst}",
            indices.len()
        );
        assert_eq!(bad, 0, "{name}");
    }
}

#[test]
fn generated_shapes_match_reference() {
    // 200k triangles exercise the multi-block (parallel) corner table.
    for shape in shapes::shapes_of_size(20_000)
        .into_iter()
        .chain(shapes::shapes_of_size(200_000))
    {
        compare(
            &shape.name,
            &shape.positions,
            &shape.normals,
            &shape.uvs,
            &shape.indices,
        );
    }
}
