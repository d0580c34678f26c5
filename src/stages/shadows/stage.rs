//! The shadow stage: the techniques made so far (each created the first
//! time it is chosen and kept, so the viewer never rebuilds), the active
//! one, and whether its light-space structure can be reused this frame.

use super::{
    FrameCheck, Lookup, LookupKind, ShadowInputs, ShadowParams, ShadowSetup, ShadowTechnique,
};
use crate::camera::Camera;
use crate::error::Result;
use crate::settings::ShadowMode;
use crate::vk::guard::Destroy;
use crate::vk::{Buffer, Context, Recorder};

/// A technique made once and kept; `stale` after the light or the spheres
/// changed while another technique was active.
struct Kept {
    technique: Box<dyn ShadowTechnique>,
    stale: bool,
}

impl Destroy for Kept {
    fn destroy_with(&mut self, ctx: &Context) {
        self.technique.destroy(ctx);
    }
}

#[derive(Default)]
pub struct ShadowStage {
    techniques: Vec<Kept>,
    /// Index into `techniques` of the active one (None = `--shadows none`).
    active: Option<usize>,
    /// The active technique's light-space structure is up to date (nothing
    /// it depends on changed since it was built): skip its passes.
    cached: bool,
    /// Reuse light-space structures while valid.
    cache: bool,
}

impl ShadowStage {
    pub fn new() -> Self {
        Self::default()
    }

    pub fn active(&self) -> Option<&dyn ShadowTechnique> {
        self.active.map(|i| self.techniques[i].technique.as_ref())
    }

    /// The active technique as its own type (tests, read-backs).
    pub fn technique<T: 'static>(&self) -> Option<&T> {
        self.active().and_then(|t| t.as_any().downcast_ref::<T>())
    }

    /// The active technique's light view.
    pub fn light(&self) -> Option<Camera> {
        self.active().map(|t| *t.light())
    }

    /// Chooses the technique of `mode`, made the first time and kept (and
    /// refitted if the light or the spheres changed since it was last
    /// active).
    pub fn choose(&mut self, mode: ShadowMode, setup: &ShadowSetup) -> Result<()> {
        let found = self
            .techniques
            .iter()
            .position(|k| k.technique.mode() == mode);
        let index = match (mode, found) {
            (ShadowMode::None, _) => None,
            (_, Some(i)) => {
                if self.techniques[i].stale {
                    self.refit(i, setup)?;
                }
                Some(i)
            }
            (_, None) => match super::create(mode, setup)? {
                Some(t) => {
                    self.techniques.push(Kept {
                        technique: t,
                        stale: false,
                    });
                    Some(self.techniques.len() - 1)
                }
                None => None,
            },
        };
        if index != self.active {
            self.cached = false;
        }
        self.active = index;
        Ok(())
    }

    fn refit(&mut self, i: usize, setup: &ShadowSetup) -> Result<()> {
        self.techniques[i].technique.refit(setup)?;
        self.techniques[i].stale = false;
        Ok(())
    }

    /// The light or the spheres changed: every technique is stale, the
    /// active one is refitted now (frames in flight read the light view
    /// from their own uniform copy, so nothing waits).
    pub fn light_changed(&mut self, setup: &ShadowSetup) -> Result<()> {
        self.cached = false;
        for k in &mut self.techniques {
            k.stale = true;
        }
        match self.active {
            Some(i) => self.refit(i, setup),
            None => Ok(()),
        }
    }

    /// Something the structures hold changed (the opacity): rebuild them
    /// in the next frame.
    pub fn uncache(&mut self) {
        self.cached = false;
    }

    /// Reuse the structure across frames while valid (off by default).
    pub fn set_cache(&mut self, on: bool) {
        self.cache = on;
        if !on {
            self.cached = false;
        }
    }

    pub fn cache(&self) -> bool {
        self.cache
    }

    /// Whether the next frame reuses the light-space structure.
    pub fn cached(&self) -> bool {
        self.cached
    }

    /// A frame that builds the structure was recorded: it serves the next
    /// ones until something it depends on changes.
    pub fn recorded(&mut self) {
        self.cached = self.cache && self.active.is_some();
    }

    /// How shade reads key-light visibility this frame: the technique's
    /// lookup, the screen-space march when there is none and SSDO runs
    /// (its parameters), or nothing.
    pub fn lookup(&self, opacity: f32, screen: Option<ShadowParams>) -> Lookup<'_> {
        match (self.active(), screen) {
            (Some(t), _) => t.lookup(opacity),
            (None, Some(p)) => Lookup::plain(LookupKind::Screen, p),
            (None, None) => Lookup::plain(LookupKind::None, ShadowParams::default()),
        }
    }

    /// The active technique's light-space passes, unless its structure is
    /// reused.
    pub fn record<'b>(&'b self, rec: &mut Recorder, f: &ShadowInputs<'b>) -> Result<()> {
        match self.active() {
            Some(t) if !self.cached => t.record_light(rec, f),
            _ => Ok(()),
        }
    }

    /// After a frame finished: `Retry` when the technique grew a structure
    /// that overflowed (rebuilt in the frame rendered again).
    pub fn after_frame(&mut self, ctx: &Context, words: &[u32]) -> Result<FrameCheck> {
        let check = match self.active {
            Some(i) => self.techniques[i].technique.after_frame(ctx, words)?,
            None => FrameCheck::Done,
        };
        if check == FrameCheck::Retry {
            self.cached = false;
        }
        Ok(check)
    }

    /// The active technique's words read after each frame.
    pub fn readback(&self) -> Option<(&Buffer, u64, u64)> {
        self.active().and_then(|t| t.readback())
    }

    /// Whether each frame must be checked before the next is recorded.
    pub fn checks_frames(&self) -> bool {
        self.active().is_some_and(|t| t.checks_frames())
    }

    /// The active technique's device memory by class.
    pub fn memory(&self) -> Vec<(&'static str, u64)> {
        self.active().map(|t| t.memory()).unwrap_or_default()
    }

    pub fn destroy(&mut self, ctx: &Context) {
        self.techniques.destroy_with(ctx);
    }
}
