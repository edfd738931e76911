//! The TOML schema of a scene file, as serde reads it. Values keep their spans so validation can say
//! where a bad value is. Unknown keys are rejected by serde with their position.

use serde::Deserialize;
use toml::Spanned;

/// Arrays of exactly `N` values. (serde's arrays take the first `N` of a longer TOML array and
/// pass over the rest: `position = [0, 0, 0, 1]` was read as `[0, 0, 0]`.)
mod exact {
    use serde::de::{Deserialize, Deserializer, Error, IgnoredAny, SeqAccess, Visitor};
    use std::marker::PhantomData;
    use toml::Spanned;

    struct Exact<T, const N: usize>([T; N]);

    impl<'de, T: Deserialize<'de> + Copy + Default, const N: usize> Deserialize<'de> for Exact<T, N> {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            struct Values<T, const N: usize>(PhantomData<T>);
            impl<'de, T: Deserialize<'de> + Copy + Default, const N: usize> Visitor<'de> for Values<T, N> {
                type Value = Exact<T, N>;
                fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                    write!(f, "an array of length {N}")
                }
                fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<Self::Value, A::Error> {
                    let mut values = [T::default(); N];
                    for (k, value) in values.iter_mut().enumerate() {
                        *value = seq
                            .next_element()?
                            .ok_or_else(|| A::Error::invalid_length(k, &self))?;
                    }
                    // Count what is left, for the message (nothing is kept).
                    let mut length = N;
                    while seq.next_element::<IgnoredAny>()?.is_some() {
                        length += 1;
                    }
                    if length != N {
                        return Err(A::Error::invalid_length(length, &self));
                    }
                    Ok(Exact(values))
                }
            }
            deserializer.deserialize_seq(Values::<T, N>(PhantomData))
        }
    }

    pub(super) fn array<'de, D, T, const N: usize>(deserializer: D) -> Result<[T; N], D::Error>
    where
        D: Deserializer<'de>,
        T: Deserialize<'de> + Copy + Default,
    {
        Ok(Exact::<T, N>::deserialize(deserializer)?.0)
    }

    pub(super) fn spanned<'de, D, const N: usize>(
        deserializer: D,
    ) -> Result<Spanned<[f64; N]>, D::Error>
    where
        D: Deserializer<'de>,
    {
        let value = Spanned::<Exact<f64, N>>::deserialize(deserializer)?;
        Ok(Spanned::new(value.span(), value.into_inner().0))
    }

    pub(super) fn some_spanned<'de, D, const N: usize>(
        deserializer: D,
    ) -> Result<Option<Spanned<[f64; N]>>, D::Error>
    where
        D: Deserializer<'de>,
    {
        spanned(deserializer).map(Some)
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    pub world: Option<WorldSection>,
    #[serde(default)]
    pub body: Vec<Spanned<BodySection>>,
    #[serde(default)]
    pub obstacle: Vec<Spanned<ObstacleSection>>,
    #[serde(default)]
    pub tool: Vec<Spanned<ToolSection>>,
    #[serde(default)]
    pub attachment: Vec<Spanned<AttachmentSection>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AttachmentSection {
    pub name: Option<Spanned<String>>,
    pub body: Option<Spanned<String>>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub at: Option<Spanned<[f64; 3]>>,
    pub radius: Option<Spanned<f64>>,
    pub to: Option<Spanned<String>>,
    pub stiffness: Option<Spanned<f64>>,
    pub damping: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct WorldSection {
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub gravity: Option<Spanned<[f64; 3]>>,
    pub dt: Option<Spanned<f64>>,
    pub air_viscosity: Option<Spanned<f64>>,
    pub integrator: Option<Spanned<String>>,
    pub helper_thread: Option<Spanned<bool>>,
    pub face_contact: Option<Spanned<bool>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BodySection {
    pub name: Option<Spanned<String>>,
    pub mesh: Option<Spanned<MeshSection>>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub position: Option<Spanned<[f64; 3]>>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub orientation: Option<Spanned<[f64; 4]>>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub velocity: Option<Spanned<[f64; 3]>>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub angular_velocity: Option<Spanned<[f64; 3]>>,
    pub surface_mass: Option<Spanned<f64>>,
    pub rigid_mass: Option<Spanned<f64>>,
    pub surface_stiffness: Option<Spanned<f64>>,
    pub surface_damping: Option<Spanned<f64>>,
    pub link_stiffness: Option<Spanned<f64>>,
    pub link_damping: Option<Spanned<f64>>,
    pub air_viscosity: Option<Spanned<f64>>,
    pub friction: Option<Spanned<f64>>,
    pub fixed: Option<bool>,
    pub self_contact: Option<Spanned<bool>>,
    pub integrator: Option<Spanned<String>>,
    pub subdivision: Option<Spanned<SubdivisionSection>>,
    pub cutting: Option<Spanned<CuttingSection>>,
    pub plasticity: Option<Spanned<PlasticitySection>>,
    pub tearing: Option<Spanned<TearingSection>>,
}

#[derive(Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a table of tearing settings, such as `{ strain = 0.3 }` (`{}` for the defaults)"
)]
pub(super) struct TearingSection {
    pub enabled: Option<bool>,
    pub strain: Option<Spanned<f64>>,
    pub ticks: Option<Spanned<u32>>,
    pub max_per_tick: Option<Spanned<u32>>,
    pub max_nodes: Option<Spanned<u32>>,
    pub max_pieces: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a table of plasticity settings, such as `{ yield = 0.002 }` (`{}` for the defaults)"
)]
pub(super) struct PlasticitySection {
    pub enabled: Option<bool>,
    #[serde(rename = "yield")]
    pub yield_: Option<Spanned<f64>>,
    pub creep: Option<Spanned<f64>>,
    pub max: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a table of cutting settings, such as `{ resistance = 0.5 }` (`{}` for the defaults)"
)]
pub(super) struct CuttingSection {
    pub enabled: Option<bool>,
    pub resistance: Option<Spanned<f64>>,
    pub min_angle: Option<Spanned<f64>>,
    pub prestress: Option<Spanned<f64>>,
    pub max_nodes: Option<Spanned<u32>>,
    pub tolerance: Option<Spanned<f64>>,
    pub max_pieces: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a table of subdivision settings, such as `{ rule = \"area\" }` (`{}` for the defaults)"
)]
pub(super) struct SubdivisionSection {
    pub enabled: Option<bool>,
    pub rule: Option<Spanned<String>>,
    pub max_depth: Option<Spanned<u8>>,
    pub min_edge: Option<Spanned<f64>>,
    pub coarsen_after: Option<Spanned<f64>>,
    pub tolerance: Option<Spanned<f64>>,
    pub zone_edge: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(
    deny_unknown_fields,
    expecting = "a table with one mesh kind, such as `{ icosphere = { radius = 0.05 } }`"
)]
pub(super) struct MeshSection {
    pub icosphere: Option<Spanned<IcosphereSection>>,
    pub ellipsoid: Option<Spanned<EllipsoidSection>>,
    #[serde(rename = "box")]
    pub box_: Option<Spanned<BoxMeshSection>>,
    pub obj: Option<Spanned<String>>,
    pub capsule: Option<Spanned<CapsuleMeshSection>>,
    pub scale: Option<Spanned<ScaleValue>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CapsuleMeshSection {
    pub radius: Spanned<f64>,
    pub length: Spanned<f64>,
    pub around: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "expected a number > 0 or three numbers > 0 (`[sx, sy, sz]`) for `scale`"
)]
pub(super) enum ScaleValue {
    Uniform(f64),
    PerAxis(#[serde(deserialize_with = "exact::array")] [f64; 3]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct IcosphereSection {
    pub radius: Spanned<f64>,
    pub subdivisions: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EllipsoidSection {
    #[serde(deserialize_with = "exact::spanned")]
    pub radii: Spanned<[f64; 3]>,
    pub subdivisions: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BoxMeshSection {
    #[serde(deserialize_with = "exact::spanned")]
    pub size: Spanned<[f64; 3]>,
    pub subdivisions: Option<Spanned<BoxSubdivisions>>,
}

#[derive(Deserialize)]
#[serde(
    untagged,
    expecting = "expected a whole number 0…100 or three of them (`[nx, ny, nz]`) for `subdivisions`"
)]
pub(super) enum BoxSubdivisions {
    Uniform(u32),
    PerAxis(#[serde(deserialize_with = "exact::array")] [u32; 3]),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObstacleSection {
    pub name: Option<Spanned<String>>,
    pub plane: Option<Spanned<PlaneSection>>,
    #[serde(rename = "box")]
    pub box_: Option<Spanned<BoxObstacleSection>>,
    pub friction: Option<Spanned<f64>>,
    pub static_friction: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct PlaneSection {
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub point: Option<Spanned<[f64; 3]>>,
    #[serde(deserialize_with = "exact::spanned")]
    pub normal: Spanned<[f64; 3]>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BoxObstacleSection {
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub center: Option<Spanned<[f64; 3]>>,
    #[serde(deserialize_with = "exact::spanned")]
    pub size: Spanned<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub orientation: Option<Spanned<[f64; 4]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ToolSection {
    pub name: Option<Spanned<String>>,
    pub shape: Option<Spanned<ToolShapeSection>>,
    pub input: Option<Spanned<String>>,
    pub script: Option<Spanned<Vec<Spanned<KeyframeSection>>>>,
    pub max_force: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ToolShapeSection {
    pub sphere: Option<Spanned<SphereSection>>,
    pub capsule: Option<Spanned<CapsuleSection>>,
    pub grasper: Option<Spanned<GrasperSection>>,
    pub blade: Option<Spanned<BladeSection>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SphereSection {
    pub radius: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CapsuleSection {
    pub radius: Spanned<f64>,
    pub length: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct GrasperSection {
    pub jaw_length: Spanned<f64>,
    pub radius: Spanned<f64>,
    pub shaft_length: Option<Spanned<f64>>,
    pub grasp_below: Option<Spanned<f64>>,
    pub release_above: Option<Spanned<f64>>,
    pub reach: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct BladeSection {
    pub length: Spanned<f64>,
    pub thickness: Spanned<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct KeyframeSection {
    pub t: Spanned<f64>,
    #[serde(deserialize_with = "exact::spanned")]
    pub position: Spanned<[f64; 3]>,
    #[serde(default, deserialize_with = "exact::some_spanned")]
    pub orientation: Option<Spanned<[f64; 4]>>,
    pub jaw: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ScriptFile {
    pub script: Spanned<Vec<Spanned<KeyframeSection>>>,
}
