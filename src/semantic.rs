//! Semantic region levels (after the semantic SSDO paper): which hierarchy level separates
//! occluders from receivers, chosen from the camera's zoom and blended
//! between neighbouring levels so zooming never pops.

use crate::camera::Camera;
use crate::scene::{MAX_LEVELS, Scene};
use glam::DVec3;

/// Half-width of the blended band around each threshold, relative to it.
pub const BAND: f64 = 0.25;
/// Ratio between successive default thresholds (must stay below
/// (1 - BAND) / (1 + BAND) = 0.6 so the bands do not overlap).
pub const STEP: f64 = 0.4;

/// The region test of one frame: regions at `level_a` and `level_b` are
/// compared, the latter with weight `blend`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelChoice {
    pub level_a: u32,
    pub level_b: u32,
    pub blend: f32,
}

/// Hierarchy levels that actually separate something (more than one
/// distinct region), outermost first. Empty when none does (an `.xyzr`
/// file without region columns, a single-region model): semantic SSDO then
/// treats every sphere as its own region, i.e. it equals plain SSDO. (Until
/// this was empty-able such scenes had one region in all, and semantic
/// SSDO found no occluder at all: no ambient occlusion in the default mode.)
pub fn useful_levels(scene: &Scene) -> Vec<u32> {
    // (an instanced scene's levels were chosen from its tree: each one
    // separates, and more than its predecessor)
    if let Some(inst) = &scene.instancing {
        return (0..inst.levels.len() as u32).collect();
    }
    let n = scene.level_names.len().min(MAX_LEVELS);
    (0..n)
        .filter(|&level| {
            let first = scene.spheres.first().map(|s| s.region[level]);
            scene.spheres.iter().any(|s| Some(s.region[level]) != first)
        })
        .map(|l| l as u32)
        .collect()
}

/// Default thresholds (world units of visible height): the first at 60% of
/// the full view, then each STEP times the previous.
pub fn default_thresholds(levels: usize, full_view_height: f64) -> Vec<f64> {
    (0..levels.saturating_sub(1))
        .map(|k| full_view_height * 0.6 * STEP.powi(k as i32))
        .collect()
}

/// How much of the world the camera shows vertically around the scene
/// centre: the orthographic view height, or for perspective the view height
/// at the scene centre's distance.
pub fn zoom_distance(cam: &Camera, scene_center: DVec3) -> f64 {
    match cam.fov_deg {
        None => cam.view_height,
        Some(f) => 2.0 * (cam.eye() - scene_center).length() * (0.5 * f.to_radians()).tan(),
    }
}

/// Picks the levels for zoom distance `d`. `thresholds` (descending) are
/// where level k+1 takes over from level k; around each, within +-BAND,
/// both levels are evaluated and blended.
pub fn choose(d: f64, thresholds: &[f64], levels: &[u32]) -> LevelChoice {
    let last = *levels.last().unwrap_or(&0);
    for (k, &t) in thresholds.iter().enumerate() {
        let (hi, lo) = (t * (1.0 + BAND), t * (1.0 - BAND));
        let (a, b) = (
            levels.get(k).copied().unwrap_or(last),
            levels.get(k + 1).copied().unwrap_or(last),
        );
        if d >= hi {
            return LevelChoice {
                level_a: a,
                level_b: a,
                blend: 0.0,
            };
        }
        if d > lo {
            return LevelChoice {
                level_a: a,
                level_b: b,
                blend: ((hi - d) / (hi - lo)) as f32,
            };
        }
    }
    let l = levels.get(thresholds.len()).copied().unwrap_or(last);
    LevelChoice {
        level_a: l,
        level_b: l,
        blend: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Sphere;

    fn scene(regions: &[[u32; 2]], levels: usize) -> Scene {
        Scene {
            spheres: regions
                .iter()
                .map(|&[a, b]| Sphere {
                    center: [0.0; 3],
                    radius: 1.0,
                    color: [255; 4],
                    region: {
                        let mut r = [0; MAX_LEVELS];
                        r[0] = a;
                        r[1] = b;
                        r
                    },
                })
                .collect(),
            level_names: (0..levels).map(|l| format!("l{l}")).collect(),
            source: "test".into(),
            instancing: None,
            expanded: false,
            atoms: None,
            origin: None,
        }
    }

    #[test]
    fn only_levels_that_separate_are_useful() {
        // no levels at all (.xyzr without region columns)
        assert!(useful_levels(&scene(&[[0, 0], [0, 0]], 0)).is_empty());
        // one model, one chain: nothing separates
        assert!(useful_levels(&scene(&[[0, 3], [0, 3]], 2)).is_empty());
        // one model, two chains
        assert_eq!(useful_levels(&scene(&[[0, 3], [0, 4]], 2)), vec![1]);
        assert_eq!(useful_levels(&scene(&[[1, 3], [2, 4]], 2)), vec![0, 1]);
        // no levels: the choice is level 0 and nothing blends
        let c = choose(10.0, &default_thresholds(0, 10.0), &[]);
        assert_eq!((c.level_a, c.level_b, c.blend), (0, 0, 0.0));
    }

    #[test]
    fn crossing_a_threshold_switches_level_through_a_blend() {
        let levels = [1, 2, 3];
        let t = default_thresholds(levels.len(), 100.0);
        assert_eq!(t.len(), 2);
        assert_eq!(
            choose(100.0, &t, &levels),
            LevelChoice {
                level_a: 1,
                level_b: 1,
                blend: 0.0
            }
        );
        let mid = choose(t[0], &t, &levels);
        assert_eq!((mid.level_a, mid.level_b), (1, 2));
        assert!((mid.blend - 0.5).abs() < 1e-6);
        // the blend rises monotonically through the band
        let mut prev = -1.0;
        for i in 0..=20 {
            let d = t[0] * (1.0 + BAND) - i as f64 * (2.0 * BAND * t[0]) / 20.0;
            let c = choose(d, &t, &levels);
            let eff = if c.level_a == 1 && c.level_b == 1 {
                0.0
            } else if c.level_a == 2 {
                1.0
            } else {
                c.blend
            };
            assert!(eff + 1e-6 >= prev, "blend not monotone at {d}: {c:?}");
            prev = eff;
        }
        assert_eq!(
            choose(t[0] * 0.7, &t, &levels),
            LevelChoice {
                level_a: 2,
                level_b: 2,
                blend: 0.0
            }
        );
        assert_eq!(
            choose(t[1] * 0.5, &t, &levels),
            LevelChoice {
                level_a: 3,
                level_b: 3,
                blend: 0.0
            }
        );
    }

    #[test]
    fn single_level_never_blends() {
        assert_eq!(
            choose(5.0, &[], &[2]),
            LevelChoice {
                level_a: 2,
                level_b: 2,
                blend: 0.0
            }
        );
    }
}
