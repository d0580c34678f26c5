//! A trivial shadow technique for unit tests: key-light visibility 0.5 on
//! every pixel, written by a pass of its own into a per-pixel buffer that
//! shade reads (`LookupKind::Buffer`, the generic way in). It exists to
//! show (and test) what adding a technique takes: this file, a `ShadowMode`
//! value, one arm in `shadows::create` (and, for a real one, its row in the
//! pass list).

use super::ShadowInputs;
use super::{Lookup, LookupKind, ShadowParams, ShadowSetup, ShadowTechnique};
use crate::camera::Camera;
use crate::error::Result;
use crate::settings::ShadowMode;
use crate::vk::pipeline::{Binding, texel};
use crate::vk::{Buffer, Context, Recorder};
use std::any::Any;

pub const NAME: &str = "test_constant";

const LOOKUP: [Binding; 1] = [texel("visibilityTex", ash::vk::Format::R32_SFLOAT)];

pub struct Constant {
    light: Camera,
    visibility: Buffer,
}

impl Constant {
    pub fn new(setup: &ShadowSetup) -> Result<Self> {
        let cam = &setup.settings.camera;
        let pixels = cam.width as u64 * cam.height as u64;
        Ok(Constant {
            light: setup.fit(16)?,
            visibility: Buffer::storage(setup.ctx, "test constant visibility", pixels * 4)?,
        })
    }
}

impl ShadowTechnique for Constant {
    fn mode(&self) -> ShadowMode {
        ShadowMode::TestConstant
    }
    fn light(&self) -> &Camera {
        &self.light
    }
    fn record_light<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        rec.pass(NAME, |p| {
            p.fill(&self.visibility, f.pixels * 4, 0.5f32.to_bits());
            Ok(())
        })
    }
    fn lookup(&self, _opacity: f32) -> Lookup<'_> {
        Lookup {
            kind: LookupKind::Buffer,
            soft: false,
            bindings: &LOOKUP,
            buffers: vec![("visibilityTex", &self.visibility)],
            params: ShadowParams::default(),
        }
    }
    fn refit(&mut self, setup: &ShadowSetup) -> Result<()> {
        self.light = setup.fit(16)?;
        Ok(())
    }
    fn memory(&self) -> Vec<(&'static str, u64)> {
        vec![]
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
    fn as_any_mut(&mut self) -> &mut dyn Any {
        self
    }
    fn destroy(&mut self, ctx: &Context) {
        self.visibility.destroy(ctx);
    }
}

#[cfg(test)]
mod tests {
    use crate::render::Renderer;
    use crate::scene::{Scene, Sphere};
    use crate::settings::{Axes, Options, ShadowMode, SsdoMode};
    use crate::vk::{Context, ContextOptions};

    #[test]
    fn a_fifth_technique_plugs_in_through_the_enum_arm() {
        let ctx = Context::new(&ContextOptions {
            validate: true,
            ..Default::default()
        })
        .expect("context");
        let scene = Scene {
            spheres: vec![Sphere {
                center: [0.0; 3],
                radius: 1.0,
                color: [200, 200, 200, 255],
                region: [0; 4],
            }],
            level_names: vec![],
            source: "one".into(),
            instancing: None,
            expanded: false,
            atoms: None,
            origin: None,
        };
        let axes = Axes {
            width: 16,
            height: 16,
            shadows: ShadowMode::TestConstant,
            ssdo: SsdoMode::Off,
            ..Axes::default()
        };
        let settings = Options::default().resolve(&axes, &scene).unwrap();
        let mut r = Renderer::new(&ctx, &scene, settings).expect("renderer");
        let times = r.render_frame().expect("frame");
        assert!(times.iter().any(|(n, _)| *n == super::NAME), "{times:?}");
        // AOVs are off by default (colour-only frames): reading them says so.
        let err = r
            .inspect()
            .read_shadow()
            .expect_err("AOVs are off")
            .to_string();
        assert!(err.contains("AOVs are off"), "{err}");
        r.update(|s| s.aovs = true).unwrap();
        r.render_frame().expect("frame");
        let vis = r.inspect().read_vis().unwrap();
        let shadow = r.inspect().read_shadow().unwrap();
        let covered = vis.iter().filter(|&&k| k != crate::gpu::VIS_EMPTY).count();
        assert!(covered > 0);
        // (the shadow AOV is unorm16: 0.5 reads back as 32768 / 65535)
        for (k, s) in vis.iter().zip(&shadow) {
            let want = if *k == crate::gpu::VIS_EMPTY {
                1.0
            } else {
                0.5
            };
            assert!((s - want).abs() < 1e-4, "{s} vs {want}");
        }
        drop(r);
        assert_eq!(
            ctx.validation_messages(),
            0,
            "{:?}",
            ctx.messages.messages()
        );
    }
}
