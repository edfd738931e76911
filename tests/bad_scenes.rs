//! Bad scenes are errors that name the file, line and column and say what was expected — never a
//! panic. Each case pins its message.

mod common;

use std::path::Path;

use palpa::scene::parse_scene;

fn error_in(text: &str, dir: &Path) -> String {
    match parse_scene(text, "bad.toml", dir) {
        Ok(_) => panic!("scene accepted:\n{text}"),
        Err(e) => e.to_string(),
    }
}

fn error_of(text: &str) -> String {
    error_in(text, &common::repo_root())
}

const BODY: &str =
    "[[body]]\nname = \"organ\"\nmesh = { icosphere = { radius = 0.05, subdivisions = 1 } }\n";

#[test]
fn toml_syntax_error_names_line_and_column() {
    let e = error_of("[world]\ngravity = [0.0, 0.0, -9.81\ndt = 0.001\n");
    // The parser notices the missing comma where the next line starts.
    assert_eq!(
        e,
        "bad.toml:3:1: missing comma between array elements, expected `,`"
    );
}

#[test]
fn unknown_key_is_an_error_with_its_place() {
    let e = error_of(&format!("{BODY}stiffnes = 3.0\n"));
    assert!(
        e.starts_with("bad.toml:4:1: unknown field `stiffnes`, expected one of"),
        "{e}"
    );
    assert!(e.contains("`surface_stiffness`"), "{e}");
    let e = error_of("[wrld]\n");
    assert!(e.starts_with("bad.toml:1:2: unknown field `wrld`"), "{e}");
}

#[test]
fn wrong_type_is_an_error_with_what_was_expected() {
    let e = error_of(&format!("{BODY}surface_mass = \"heavy\"\n"));
    assert!(
        e.starts_with("bad.toml:4:16: invalid type: string \"heavy\", expected f64"),
        "{e}"
    );
    let e = error_of("[world]\nhelper_thread = 2\n");
    assert!(
        e.starts_with("bad.toml:2:17: invalid type: integer `2`, expected a boolean"),
        "{e}"
    );
    let e = error_of(&format!("{BODY}position = [0.0, 1.0]\n"));
    assert!(e.starts_with("bad.toml:4:12: "), "{e}");
    assert!(
        e.contains("expected an array of length 3") || e.contains("length 3"),
        "{e}"
    );
}

#[test]
fn non_positive_mass_and_stiffness_are_errors() {
    let e = error_of(&format!("{BODY}surface_mass = -1.0\n"));
    assert_eq!(
        e,
        "bad.toml:4:16: `surface_mass` must be a finite number > 0, found -1"
    );
    let e = error_of(&format!("{BODY}rigid_mass = 0.0\n"));
    assert_eq!(
        e,
        "bad.toml:4:14: `rigid_mass` must be a finite number > 0, found 0"
    );
    let e = error_of(&format!("{BODY}link_stiffness = 0.0\n"));
    assert_eq!(
        e,
        "bad.toml:4:18: `link_stiffness` must be a finite number > 0, found 0"
    );
    let e = error_of(&format!("{BODY}surface_stiffness = nan\n"));
    assert_eq!(
        e,
        "bad.toml:4:21: `surface_stiffness` must be a finite number > 0, found NaN"
    );
    let e = error_of(&format!("{BODY}link_damping = -0.1\n"));
    assert_eq!(
        e,
        "bad.toml:4:16: `link_damping` must be a finite number ≥ 0, found -0.1"
    );
    let e = error_of("[world]\ndt = 0.0\n");
    assert_eq!(e, "bad.toml:2:6: `dt` must be a finite number > 0, found 0");
}

#[test]
fn zero_plane_normal_is_an_error() {
    let e = error_of(
        "[[obstacle]]\nname = \"floor\"\nplane = { point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 0.0] }\n",
    );
    assert_eq!(e, "bad.toml:3:45: `normal` must be a non-zero vector");
}

#[test]
fn obstacle_needs_exactly_one_shape_and_sane_friction() {
    let e = error_of("[[obstacle]]\nname = \"floor\"\nfriction = 0.3\n");
    assert!(
        e.starts_with("bad.toml:1:1: obstacle `floor` must have exactly one of"),
        "{e}"
    );
    let e = error_of(
        "[[obstacle]]\nplane = { normal = [0.0, 0.0, 1.0] }\nfriction = 0.5\nstatic_friction = 0.2\n",
    );
    assert_eq!(
        e,
        "bad.toml:4:19: `static_friction` (0.2) must be at least `friction` (0.5)"
    );
    let e = error_of("[[obstacle]]\nbox = { size = [1.0, 0.0, 1.0] }\n");
    assert_eq!(
        e,
        "bad.toml:2:16: `size` must be three finite numbers > 0, found [1.0, 0.0, 1.0]"
    );
}

#[test]
fn bad_quaternion_is_an_error() {
    let e = error_of(&format!("{BODY}orientation = [1.0, 1.0, 0.0, 0.0]\n"));
    assert!(
        e.starts_with("bad.toml:4:15: `orientation` must be a unit quaternion [w, x, y, z]"),
        "{e}"
    );
}

#[test]
fn mesh_must_be_exactly_one_kind_with_valid_sizes() {
    let e = error_of(
        "[[body]]\nmesh = { icosphere = { radius = 0.1 }, box = { size = [1.0, 1.0, 1.0] } }\n",
    );
    assert!(
        e.starts_with("bad.toml:2:8: `mesh` must have exactly one of"),
        "{e}"
    );
    let e = error_of("[[body]]\nmesh = { icosphere = { radius = 0.0 } }\n");
    assert_eq!(
        e,
        "bad.toml:2:33: `radius` must be a finite number > 0, found 0"
    );
    let e = error_of("[[body]]\nname = \"x\"\n");
    assert_eq!(e, "bad.toml:1:1: body `x` needs a `mesh`");
    let e = error_of("[[body]]\nmesh = { icosphere = { radius = 0.1, subdivisions = 12 } }\n");
    assert_eq!(
        e,
        "bad.toml:2:53: `subdivisions` must be at most 7, found 12"
    );
}

#[test]
fn duplicate_names_are_errors() {
    let e = error_of(&format!("{BODY}{BODY}"));
    assert_eq!(e, "bad.toml:5:8: duplicate body name `organ`");
}

/// Writes an OBJ file into a fresh directory and returns the directory.
fn obj_dir(name: &str, obj: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("palpa-bad-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.obj"), obj).unwrap();
    dir
}

const CUBE_VERTICES: &str =
    "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n";
const CUBE_FACES: [&str; 12] = [
    "f 1 3 2", "f 1 4 3", "f 5 6 7", "f 5 7 8", "f 1 2 6", "f 1 6 5", "f 2 3 7", "f 2 7 6",
    "f 3 4 8", "f 3 8 7", "f 4 1 5", "f 4 5 8",
];
const OBJ_BODY: &str = "[[body]]\nmesh = { obj = \"m.obj\", scale = 0.1 }\n";

#[test]
fn a_closed_obj_cube_loads() {
    let dir = obj_dir(
        "cube",
        &format!("{CUBE_VERTICES}{}\n", CUBE_FACES.join("\n")),
    );
    let scene = parse_scene(OBJ_BODY, "ok.toml", &dir).unwrap();
    assert_eq!(scene.bodies[0].mesh.vertex_count(), 8);
    // Re-centred on the surface centre and scaled: the cube spans ±0.05 m.
    let max_x = scene.bodies[0]
        .mesh
        .positions_in_body
        .iter()
        .map(|p| p.x)
        .fold(f64::MIN, f64::max);
    assert!((max_x - 0.05).abs() < 1e-12);
    std::fs::remove_dir_all(dir).unwrap();
}

/// The plain cube's enclosed volume and vertex count, read through a scene.
fn cube_as_read(name: &str, obj: &str) -> (usize, usize, f64) {
    let dir = obj_dir(name, obj);
    let scene = parse_scene(OBJ_BODY, "ok.toml", &dir).unwrap_or_else(|e| panic!("{name}: {e}"));
    std::fs::remove_dir_all(dir).unwrap();
    let mesh = &scene.bodies[0].mesh;
    (
        mesh.vertex_count(),
        mesh.triangles.len(),
        mesh.signed_volume(),
    )
}

#[test]
fn an_obj_written_in_groups_or_as_separate_triangles_is_the_surface_it_describes() {
    let plain = cube_as_read(
        "plain",
        &format!("{CUBE_VERTICES}{}\n", CUBE_FACES.join("\n")),
    );
    assert_eq!((plain.0, plain.1), (8, 12));
    assert!((plain.2 - 1e-3).abs() < 1e-15, "{plain:?}");
    // As an exporter writes it: an object, two groups with their own materials sharing the
    // cube's vertices, smoothing groups, quads with texture coordinates and normals, negative
    // indices, a line, CRLF line ends and tabs.
    let exported = "mtllib cube.mtl\r\no Cube\r\nv 0 0 0\r\nv 1 0 0\r\nv 1 1 0\r\nv 0 1 0\r\n\
                    v 0 0 1\r\nv 1 0 1\r\nv 1 1 1\r\nv 0 1 1\r\nvt 0 0\r\nvn 0 0 1\r\n\
                    g top\r\nusemtl red\r\ns 1\r\nf\t5/1/1 6/1/1 7/1/1 8/1/1\r\nf -8//1 -5//1 -6//1 -7//1\r\n\
                    g sides\r\nusemtl blue\r\ns off\r\nf 1 2 6 5\r\nf 2 3 7 6\r\nf 3 4 8 7\r\n\
                    f 4/1 1/1 5/1 8/1\r\nl 1 7\r\n";
    assert_eq!(cube_as_read("exported", exported), plain);
    // A triangle soup (as converted from STL): every triangle with vertices of its own.
    assert_eq!(cube_as_read("soup", &soup(&CUBE_FACES)), plain);
}

/// The cube's faces as a triangle soup: each triangle with three vertices of its own.
fn soup(faces: &[&str]) -> String {
    let corners: Vec<&str> = CUBE_VERTICES.lines().collect();
    let mut soup = String::new();
    for face in faces {
        for index in face.split_whitespace().skip(1) {
            soup += corners[index.parse::<usize>().unwrap() - 1];
            soup += "\n";
        }
    }
    for t in 0..faces.len() {
        soup += &format!("f {} {} {}\n", 3 * t + 1, 3 * t + 2, 3 * t + 3);
    }
    soup
}

#[test]
fn an_obj_error_names_the_vertices_as_numbered_in_the_file() {
    // Two vertices no face uses, first in the file, before the cube with a hole: the edge is
    // still that of the file's vertices 5 and 9 (the cube's 3 and 7).
    let dir = obj_dir(
        "hole-after-unused",
        &format!(
            "v 9 9 9\nv 8 8 8\n{CUBE_VERTICES}{}\n",
            CUBE_FACES[..11]
                .iter()
                .map(|f| {
                    let i: Vec<usize> = f
                        .split_whitespace()
                        .skip(1)
                        .map(|w| w.parse().unwrap())
                        .collect();
                    format!("f {} {} {}", i[0] + 2, i[1] + 2, i[2] + 2)
                })
                .collect::<Vec<_>>()
                .join("\n")
        ),
    );
    let e = error_in(OBJ_BODY, &dir);
    assert_eq!(
        e,
        "bad.toml:2:8: mesh (obj m.obj): the mesh is not a closed manifold: the edge between vertices 5 and 9 (0-based) is used by 1 triangle(s), expected 2"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn an_obj_error_names_the_file_vertices_a_merged_vertex_stands_for() {
    // The cube as a soup without its last triangle (the cube's `f 4 5 8`): the hole's edge, the
    // cube's corners 4 and 8, is named by the first vertex at each of its ends (the file's 4 and
    // 11), each with the others at its position, so that the edge can be found in the file's
    // faces (the cube's `f 3 4 8` is the file's 24, 25, 26).
    let dir = obj_dir("soup-hole", &soup(&CUBE_FACES[..11]));
    let e = error_in(OBJ_BODY, &dir);
    assert_eq!(
        e,
        "bad.toml:2:8: mesh (obj m.obj): the mesh is not a closed manifold: the edge between \
         vertices 4 and 11 (0-based) is used by 1 triangle(s), expected 2; vertex 4 also stands for \
         the file's 25, 30, vertex 11 also stands for the file's 26, 28 (vertices at one position \
         are merged into the first)"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn obj_with_a_hole_is_not_a_closed_manifold() {
    let dir = obj_dir(
        "hole",
        &format!("{CUBE_VERTICES}{}\n", CUBE_FACES[..11].join("\n")),
    );
    let e = error_in(OBJ_BODY, &dir);
    assert_eq!(
        e,
        "bad.toml:2:8: mesh (obj m.obj): the mesh is not a closed manifold: the edge between vertices 3 and 7 (0-based) is used by 1 triangle(s), expected 2"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn obj_with_a_flipped_face_is_inconsistently_oriented() {
    let mut faces = CUBE_FACES.to_vec();
    faces[0] = "f 1 2 3";
    let dir = obj_dir("flip", &format!("{CUBE_VERTICES}{}\n", faces.join("\n")));
    let e = error_in(OBJ_BODY, &dir);
    assert!(
        e.starts_with("bad.toml:2:8: mesh (obj m.obj): the mesh is not consistently oriented"),
        "{e}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn obj_with_a_degenerate_triangle_is_an_error() {
    // A closed tetrahedron-like shape whose one triangle has three collinear corners.
    let obj = "v 0 0 0\nv 1 0 0\nv 2 0 0\nv 1 1 0\nv 1 0.5 1\n\
               f 1 2 3\nf 1 3 4\nf 1 5 2\nf 2 5 3\nf 3 5 4\nf 4 5 1\n";
    let dir = obj_dir("degenerate", obj);
    let e = error_in(OBJ_BODY, &dir);
    assert!(
        e.starts_with(
            "bad.toml:2:8: mesh (obj m.obj): triangle 0 (vertices 0, 1, 2, 0-based) is degenerate"
        ),
        "{e}"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn obj_touching_itself_at_a_vertex_is_not_a_manifold() {
    // Two tetrahedra sharing only vertex 1.
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv -1 0 0\nv 0 -1 0\nv 0 0 -1\n\
               f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n\
               f 1 5 6\nf 1 7 5\nf 1 6 7\nf 5 7 6\n";
    let dir = obj_dir("pinch", obj);
    let e = error_in(OBJ_BODY, &dir);
    assert_eq!(
        e,
        "bad.toml:2:8: mesh (obj m.obj): the mesh is not a manifold at vertex 0 (0-based): its triangles form more than one fan"
    );
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn missing_obj_file_is_an_error_at_the_path() {
    let e = error_of("[[body]]\nmesh = { obj = \"no/such/file.obj\" }\n");
    assert!(
        e.starts_with("bad.toml:2:16: mesh: cannot read OBJ file "),
        "{e}"
    );
    assert!(e.contains("no/such/file.obj"), "{e}");
}

#[test]
fn missing_scene_file_is_an_error() {
    let e = palpa::scene::load_scene(Path::new("no/such/scene.toml"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("no/such/scene.toml: cannot read the scene file:"),
        "{e}"
    );
}

#[test]
fn bad_subdivision_settings_are_errors_with_their_place() {
    let e = error_of(&format!("{BODY}subdivision = {{ rule = \"fancy\" }}\n"));
    assert_eq!(
        e,
        "bad.toml:4:24: `rule` must be \"angle\", \"constant_kl\" or \"area\", found \"fancy\""
    );
    let e = error_of(&format!("{BODY}subdivision = {{ max_depth = 0 }}\n"));
    assert_eq!(e, "bad.toml:4:29: `max_depth` must be 1 to 8, found 0");
    let e = error_of(&format!("{BODY}subdivision = {{ min_edge = -0.001 }}\n"));
    assert!(
        e.starts_with("bad.toml:4:28: `min_edge` must be a finite number > 0"),
        "{e}"
    );
    let e = error_of(&format!("{BODY}subdivision = {{ zone_edge = 0.0 }}\n"));
    assert!(
        e.starts_with("bad.toml:4:29: `zone_edge` must be a finite number > 0"),
        "{e}"
    );
    let e = error_of(&format!("{BODY}subdivision = {{ depth = 3 }}\n"));
    assert!(e.starts_with("bad.toml:4:"), "{e}");
    assert!(e.contains("unknown field `depth`"), "{e}");
    // Switched off, the body has none.
    let scene = common::scene(&format!("{BODY}subdivision = {{ enabled = false }}\n"));
    assert!(scene.bodies[0].params.subdivision.is_none());
    let scene = common::scene(&format!("{BODY}subdivision = {{}}\n"));
    assert!(scene.bodies[0].params.subdivision.is_some());
}

#[test]
fn mesh_sizes_out_of_range_are_errors_with_their_place() {
    let cases = [
        (
            "[[body]]\nmesh = { icosphere = { radius = 0.05 }, scale = 0.0 }\n",
            "bad.toml:2:49: `scale` must be a number > 0 or three numbers > 0, found 0",
        ),
        (
            "[[body]]\nmesh = { icosphere = { radius = 0.05 }, scale = [1.0, -2.0, 1.0] }\n",
            "bad.toml:2:49: `scale` must be a number > 0 or three numbers > 0, found [1, -2, 1]",
        ),
        (
            "[[body]]\nmesh = { box = { size = [0.1, 0.1, 0.1], subdivisions = [1, 101, 1] } }\n",
            "bad.toml:2:57: `subdivisions` must be at most 100 (per axis), found [1, 101, 1]",
        ),
        (
            "[[body]]\nmesh = { capsule = { radius = 0.01, length = 0.05, around = 5 } }\n",
            "bad.toml:2:61: `around` must be 6 to 256, found 5",
        ),
        (
            "[[body]]\nmesh = { capsule = { radius = 0.01, length = 1000.0, around = 256 } }\n",
            "bad.toml:2:20: the capsule would have about 1043071232 vertices, more than a scene may have",
        ),
    ];
    for (text, expected) in cases {
        assert_eq!(error_of(text), expected, "{text}");
    }
    // Seven spheres of 163 842 vertices pass the scene's 2^20: the seventh is refused where its
    // mesh is, before it is built.
    let mut text = String::new();
    for k in 0..7 {
        text += &format!(
            "[[body]]\nname = \"b{k}\"\nmesh = {{ icosphere = {{ radius = 0.05, subdivisions = 7 }} }}\n"
        );
    }
    assert_eq!(
        error_of(&text),
        "bad.toml:21:8: the scene's meshes would have 1146894 vertices with this one (163842), \
         more than the 1048576 a scene may have"
    );
}

#[test]
fn a_value_of_the_wrong_shape_says_what_was_expected_in_the_scene_s_words() {
    // Not serde's names for the scene's Rust types ("untagged enum ScaleValue", "struct
    // SubdivisionSection"), found by a reader writing scenes from the README.
    let e = error_of("[[body]]\nmesh = { icosphere = { radius = 0.05 }, scale = [0.1, 0.1] }\n");
    assert_eq!(
        e,
        "bad.toml:2:49: expected a number > 0 or three numbers > 0 (`[sx, sy, sz]`) for `scale`"
    );
    let e = error_of("[[body]]\nmesh = { icosphere = { radius = 0.05 } }\nsubdivision = true\n");
    assert_eq!(
        e,
        "bad.toml:3:15: invalid type: boolean `true`, expected a table of subdivision settings, \
         such as `{ rule = \"area\" }` (`{}` for the defaults)"
    );
    let e =
        error_of("[[body]]\nmesh = { box = { size = [0.1, 0.1, 0.1], subdivisions = \"x\" } }\n");
    assert_eq!(
        e,
        "bad.toml:2:57: expected a whole number 0…100 or three of them (`[nx, ny, nz]`) for \
         `subdivisions`"
    );
    let e = error_of("[[body]]\nmesh = \"ball\"\n");
    assert_eq!(
        e,
        "bad.toml:2:8: invalid type: string \"ball\", expected a table with one mesh kind, such as \
         `{ icosphere = { radius = 0.05 } }`"
    );
}

#[test]
fn a_key_given_twice_is_named() {
    // toml says only `duplicate key`; the message names it (its text at the error's place).
    assert_eq!(
        error_of("[world]\ndt = 0.001\ndt = 0.002\n"),
        "bad.toml:3:1: duplicate key `dt` (a key may be given once in a table)"
    );
    assert_eq!(
        error_of("[[body]]\nmesh = { icosphere = { radius = 0.03, radius = 0.04 } }\n"),
        "bad.toml:2:39: duplicate key `radius` (a key may be given once in a table)"
    );
}

#[test]
fn an_array_longer_than_its_key_takes_is_an_error_not_cut_short() {
    // Found by a reader's scenes: serde's arrays took the first three numbers of
    // `position = [0, 0, 0, 1]` and passed over the rest, and the scene was valid.
    let cases = [
        (
            format!("{BODY}position = [0.0, 0.0, 0.0, 1.0]\n"),
            "bad.toml:4:12: invalid length 4, expected an array of length 3",
        ),
        (
            format!("{BODY}orientation = [1.0, 0.0, 0.0, 0.0, 0.0]\n"),
            "bad.toml:4:15: invalid length 5, expected an array of length 4",
        ),
        (
            "[world]\ngravity = [0.0, 0.0, -9.81, 5.0]\n".to_string(),
            "bad.toml:2:11: invalid length 4, expected an array of length 3",
        ),
        (
            "[[obstacle]]\nplane = { normal = [0.0, 0.0, 1.0, 7.0] }\n".to_string(),
            "bad.toml:2:20: invalid length 4, expected an array of length 3",
        ),
        (
            "[[body]]\nmesh = { ellipsoid = { radii = [0.1, 0.1, 0.1, 0.1] } }\n".to_string(),
            "bad.toml:2:32: invalid length 4, expected an array of length 3",
        ),
        (
            "[[tool]]\nshape = { sphere = { radius = 0.004 } }\n\
             script = [ { t = 0.0, position = [0.0, 0.0, 0.3, 1.0] } ]\n"
                .to_string(),
            "bad.toml:3:34: invalid length 4, expected an array of length 3",
        ),
        (
            "[[body]]\nmesh = { icosphere = { radius = 0.05 }, scale = [0.1, 0.1, 0.1, 0.1] }\n"
                .to_string(),
            "bad.toml:2:49: expected a number > 0 or three numbers > 0 (`[sx, sy, sz]`) for `scale`",
        ),
        (
            "[[body]]\nmesh = { box = { size = [0.1, 0.1, 0.1], subdivisions = [2, 2, 2, 2] } }\n"
                .to_string(),
            "bad.toml:2:57: expected a whole number 0…100 or three of them (`[nx, ny, nz]`) for \
             `subdivisions`",
        ),
    ];
    for (text, message) in cases {
        assert_eq!(error_of(&text), message, "{text}");
    }
    // The right lengths are read as before.
    let scene = parse_scene(
        &format!("{BODY}position = [0.0, 0.0, 0.5]\norientation = [1.0, 0.0, 0.0, 0.0]\n"),
        "good.toml",
        &common::repo_root(),
    )
    .expect("valid");
    assert_eq!(scene.bodies[0].placement.position_in_world.z, 0.5);
}

/// Messages a reader writing scenes from the README found unclear (2026-12-07), each as it reads
/// now.
#[test]
fn messages_found_unclear_by_a_reader_say_what_is_wrong() {
    // Bytes that are not UTF-8: named at the first bad byte (there was no place at all).
    let dir = obj_dir("not-utf8", "");
    let path = dir.join("bad.toml");
    std::fs::write(&path, b"[world]\ndt = \xff0.001\n").unwrap();
    let e = palpa::scene::load_scene(&path).unwrap_err().to_string();
    assert_eq!(
        e,
        format!(
            "{}:2:6: byte 13 (0xff) is not UTF-8 text: a scene file is UTF-8 TOML",
            path.display()
        )
    );
    std::fs::remove_dir_all(&dir).unwrap();
    // An attachment in a scene with no bodies (was "expected one of " and nothing).
    assert_eq!(
        error_of("[[attachment]]\nbody = \"zzz\"\nat = [0.0, 0.0, 0.0]\nradius = 0.01\n"),
        "bad.toml:2:8: `body` of attachment `attachment0` names no body: found \"zzz\", the scene \
         has no bodies"
    );
    // One number for a box's subdivisions, told as written (was "found [101, 101, 101]").
    assert_eq!(
        error_of("[[body]]\nmesh = { box = { size = [0.1, 0.1, 0.1], subdivisions = 101 } }\n"),
        "bad.toml:2:57: `subdivisions` must be at most 100 (per axis), found 101"
    );
    // A degenerate triangle naming a merged vertex twice notes it once, with its figures short.
    let dir = obj_dir(
        "merged-twice",
        "v 0 0 0\nv 0.02 0 0\nv 0 0.02 0\nv 0 0 0.02\nv 0 0 0\n\
         f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\nf 5 1 2\n",
    );
    assert_eq!(
        error_in("[[body]]\nmesh = { obj = \"m.obj\" }\n", &dir),
        "bad.toml:2:8: mesh (obj m.obj): triangle 4 (vertices 0, 0, 1, 0-based) is degenerate: \
         area 0.000e0 m² for a longest edge of 2.000e-2 m; vertex 0 also stands for the file's 4 \
         (vertices at one position are merged into the first)"
    );
    std::fs::remove_dir_all(dir).unwrap();
    // A radius that overflows the mesh is named in short (was 300 digits).
    let e = error_of("[[body]]\nmesh = { icosphere = { radius = 1e300 } }\n");
    assert!(e.contains("(icosphere r=1e300 s=2)"), "{e}");
}
