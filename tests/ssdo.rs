//! Semantic SSDO: sample distribution of the shader's own
//! Halton/Malley code, occlusion on flat vs. creviced geometry, the semantic
//! region rule against plain mode, the bilateral blur on a synthetic
//! G-buffer, and the zoom-driven level choice. All under validation.

mod common;

use common::*;
use glam::DVec3;
use sphereshade::camera::Camera;
use sphereshade::gpu::Globals;
use sphereshade::passes::spirv;
use sphereshade::passes::tiles::Tiles;
use sphereshade::render::{Renderer, level_choice};
use sphereshade::scene::{self, Scene, Sphere};
use sphereshade::settings::{ShadowMode, SsdoMode};
use sphereshade::stages::ssdo::blur::{Axis, BlurIo, BlurPass, BlurPush, BlurShape};
use sphereshade::stages::ssdo::record::Record;
use sphereshade::vk::Grid;
use sphereshade::vk::pipeline::{PipelineDesc, uniform, wo};
use sphereshade::vk::{Buffer, ComputePipeline, Context};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct SamplePush {
    normal: [f32; 4],
    count: u32,
    rot: f32,
    pad: [u32; 2],
}

#[test]
fn hemisphere_samples_are_cosine_weighted() {
    let ctx = validated_context();
    let mut p = ComputePipeline::new(
        &ctx,
        &PipelineDesc {
            name: "sample probe",
            shader: spirv::TEST_SAMPLES_COMP,
            bindings: &[wo("Out"), uniform("SampleTable")],
            push_size: 32,
            local_size: 64,
            constants: &[],
            scene: 0,
        },
    )
    .expect("pipeline");
    let n = 8192u32;
    let mut out = Buffer::storage(&ctx, "samples", n as u64 * 16).expect("buffer");
    // The table SSDO itself binds.
    let mut ssdo = sphereshade::stages::ssdo::passes::SsdoPass::new(&ctx, 0).expect("ssdo");
    for (normal, rot) in [
        ([0.0f32, 0.0, 1.0], 0.0f32),
        ([0.3, -0.8, 0.2], 0.37),
        ([0.0, 0.0, -1.0], 0.81),
    ] {
        let len = (normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2]).sqrt();
        let nn = [normal[0] / len, normal[1] / len, normal[2] / len];
        let push = SamplePush {
            normal: [normal[0], normal[1], normal[2], 0.0],
            count: n,
            rot,
            pad: [0; 2],
        };
        ctx.one_shot_passes("samples", |rec| {
            rec.pass("samples", |pass| {
                pass.dispatch(
                    &p,
                    &push,
                    Grid::Groups([n / 64, 1, 1]),
                    &[("Out", &out), ("SampleTable", ssdo.table())],
                );
                Ok(())
            })
        })
        .expect("run");
        let d: Vec<[f32; 4]> = out.download_pod(&ctx, 0, n as u64).expect("read");
        let cos: Vec<f64> = d
            .iter()
            .map(|v| (v[0] * nn[0] + v[1] * nn[1] + v[2] * nn[2]) as f64)
            .collect();
        assert!(
            cos.iter().all(|&c| c >= -1e-5),
            "a sample left the upper hemisphere"
        );
        assert!(
            d.iter()
                .all(|v| ((v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt() - 1.0).abs() < 1e-4)
        );
        let mean = cos.iter().sum::<f64>() / n as f64;
        // cosine-weighted: E[cos] = 2/3 (uniform would give 1/2)
        eprintln!("normal {normal:?}: mean cos = {mean:.4}");
        assert!(
            (mean - 2.0 / 3.0).abs() < 0.01,
            "mean cos {mean} is not 2/3"
        );
    }
    out.destroy(&ctx);
    ssdo.destroy(&ctx);
    p.destroy(&ctx);
    assert_no_validation_messages(&ctx);
}

fn with_region(mut s: Sphere, r: u32) -> Sphere {
    s.region = [r, 0, 0, 0];
    s
}

/// A flat layer (region 0) plus two pits: a small sphere surrounded by big
/// wall spheres, the first pit's walls in the receiver's region (1), the
/// second's in another (2, 3). Camera and light straight down.
fn pits_scene() -> (Scene, Camera, [DVec3; 2]) {
    let mut s = Vec::new();
    for iz in 0..12 {
        for ix in 0..12 {
            s.push(with_region(
                sphere([ix as f32 * 1.8 - 40.0, 0.0, iz as f32 * 1.8 - 10.0], 1.0),
                0,
            ));
        }
    }
    let pits = [DVec3::new(0.0, 0.0, 0.0), DVec3::new(14.0, 0.0, 0.0)];
    for (k, c) in pits.iter().enumerate() {
        let recv = 1 + 2 * k as u32;
        s.push(with_region(sphere([c.x as f32, 0.0, 0.0], 1.0), recv));
        let wall = if k == 0 { recv } else { recv + 1 };
        for j in 0..8 {
            let a = j as f32 * std::f32::consts::TAU / 8.0;
            s.push(with_region(
                sphere([c.x as f32 + 3.0 * a.cos(), 1.5, 3.0 * a.sin()], 2.4),
                wall,
            ));
        }
    }
    let mut scene = scene_of(s, "pits");
    scene.level_names = vec!["group".into()];
    let cam = Camera::new(
        DVec3::new(-5.0, 0.0, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 0.0, -1.0),
        30.0,
        None,
        400,
        200,
    )
    .expect("camera");
    (scene, cam, pits)
}

fn ambient(ctx: &Context, scene: &Scene, cam: Camera, mode: SsdoMode, blur: bool) -> Vec<f32> {
    let mut s = settings(cam, ShadowMode::None);
    s.ssdo = mode;
    s.ssdo_knobs.blur = blur;
    s.light = DVec3::new(0.0, -1.0, 0.0);
    let mut r = Renderer::new(ctx, scene, s).expect("renderer");
    r.render_frame().expect("frame");
    r.inspect()
        .read_ambient()
        .expect("ambient")
        .iter()
        .map(|a| a[0])
        .collect()
}

/// Mean of `ao` over a small disk of pixels around the world point p.
fn ao_at(ao: &[f32], cam: &Camera, p: DVec3, radius_px: i64) -> f32 {
    let q = p - cam.center;
    let ppu = cam.pixels_per_unit();
    let px = (q.dot(cam.right) * ppu + 0.5 * cam.width as f64 - 0.5).round() as i64;
    let py = (0.5 * cam.height as f64 - q.dot(cam.up) * ppu - 0.5).round() as i64;
    let mut sum = 0.0;
    let mut n = 0;
    for dy in -radius_px..=radius_px {
        for dx in -radius_px..=radius_px {
            if dx * dx + dy * dy <= radius_px * radius_px {
                sum += ao[((py + dy) * cam.width as i64 + px + dx) as usize];
                n += 1;
            }
        }
    }
    sum / n as f32
}

#[test]
fn flat_layer_is_open_crevice_is_occluded_and_semantic_ignores_own_region() {
    let ctx = validated_context();
    let (scene, cam, pits) = pits_scene();
    let plain = ambient(&ctx, &scene, cam, SsdoMode::Plain, false);
    let semantic = ambient(&ctx, &scene, cam, SsdoMode::Semantic, false);
    let top = |c: DVec3| c + DVec3::new(0.0, 1.0, 0.0);
    // sphere tops in the middle of the flat layer
    let mut flat = 0.0;
    let mut k = 0;
    for iz in 4..8 {
        for ix in 4..8 {
            flat += ao_at(
                &plain,
                &cam,
                top(DVec3::new(
                    ix as f64 * 1.8 - 40.0,
                    0.0,
                    iz as f64 * 1.8 - 10.0,
                )),
                1,
            );
            k += 1;
        }
    }
    let flat = flat / k as f32;
    let (p_same, p_diff) = (
        ao_at(&plain, &cam, top(pits[0]), 1),
        ao_at(&plain, &cam, top(pits[1]), 1),
    );
    let (s_same, s_diff) = (
        ao_at(&semantic, &cam, top(pits[0]), 1),
        ao_at(&semantic, &cam, top(pits[1]), 1),
    );
    eprintln!(
        "flat {flat:.3}; plain pits {p_same:.3} {p_diff:.3}; semantic pits (same region) {s_same:.3} (other region) {s_diff:.3}"
    );
    assert!(flat > 0.8, "a flat layer is occluded: {flat}");
    assert!(
        p_same < flat - 0.2 && p_diff < flat - 0.2,
        "crevices are not darker than the flat layer"
    );
    assert!(
        s_same > 0.95,
        "semantic mode counts occluders of the receiver's own region: {s_same}"
    );
    assert!(
        (s_diff - p_diff).abs() < 0.05,
        "semantic mode drops occluders of other regions: {s_diff} vs {p_diff}"
    );
    assert_no_validation_messages(&ctx);
}

#[test]
fn bilateral_blur_keeps_depth_edges_and_smooths_flat_areas() {
    // Per pixel (edge keys as ssdo packs them) and per 2x2 block (records
    // as ssdo_prep packs them).
    for half in [false, true] {
        blur_keeps_edges(half);
    }
}

/// A 64x32 grid of pixels or blocks: the left half a flat layer at view
/// distance 0 with noisy ambient visibility around 0.2, the right half 50
/// units behind with visibility around 0.9; every normal faces the camera.
fn blur_keeps_edges(half: bool) {
    let ctx = validated_context();
    let (w, h) = (64u32, 32u32);
    let n = (w * h) as usize;
    let k = if half { 2 } else { 1 };
    let cam = Camera::new(
        DVec3::ZERO,
        DVec3::new(0.0, 0.0, -1.0),
        DVec3::Y,
        32.0 * k as f64,
        None,
        k * w,
        k * h,
    )
    .expect("camera");
    let offset = 100.0;
    let mut globals = Globals {
        cam: cam.to_gpu(offset),
        light: cam.to_gpu(offset),
        ..Default::default()
    };
    globals.counts = if half {
        [1, w, h, 0]
    } else {
        [1, w / 2, h / 2, 0]
    };
    // the active rectangle: every pixel
    globals.params = [0.0, 0.0, (k * w) as f32, (k * h) as f32];
    let mut records = vec![[0u32; 4]; n];
    let mut keys = vec![0u32; n];
    let mut amb = vec![0.0f32; n];
    let mut ao_in = vec![0u32; n];
    let mut seed = 12345u32;
    let mut noise = || {
        seed = seed.wrapping_mul(1664525).wrapping_add(1013904223);
        (seed >> 8) as f32 / (1 << 24) as f32 - 0.5
    };
    for y in 0..h {
        for x in 0..w {
            let i = (y * w + x) as usize;
            let left = x < w / 2;
            let z = if left { 0.0f32 } else { 50.0 };
            keys[i] = z.to_bits() & 0xFFFF_F000; // blur_key, region 0
            records[i] = Record {
                z,
                normal: [0.0, 0.0, 1.0],
                region_a: 0,
                region_b: 0,
                sub: [0, 0],
                radiance: [0.0; 3],
                visibility: 1.0,
                covered: true,
            }
            .pack();
            amb[i] = if left { 0.2 } else { 0.9 } + 0.2 * noise();
            // pack_ao: near visibility, far visibility 1, no bounce
            ao_in[i] = (amb[i].clamp(0.0, 1.0) * 255.0 + 0.5) as u32 | (255 << 8) | (15 << 28);
        }
    }
    let up = |name: &str, data: &[u8], usage| {
        let b = Buffer::new(
            &ctx,
            name,
            data.len() as u64,
            usage,
            gpu_allocator::MemoryLocation::GpuOnly,
        )
        .expect("buffer");
        b.upload(&ctx, 0, data).expect("upload");
        b
    };
    let st =
        ash::vk::BufferUsageFlags::STORAGE_BUFFER | ash::vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
    let mut bufs = vec![
        up(
            "globals",
            bytemuck::bytes_of(&globals),
            ash::vk::BufferUsageFlags::UNIFORM_BUFFER,
        ),
        up("ao in", bytemuck::cast_slice(&ao_in), st),
        up("ao tmp", &vec![0u8; n * 4], st),
        up("ao out", &vec![0u8; n * 4], st),
        up("records", bytemuck::cast_slice(&records), st),
        up("keys", bytemuck::cast_slice(&keys), st),
    ];
    let mut blur = BlurPass::new();
    blur.prepare(&ctx, false, false).expect("pipelines");
    let push = BlurPush {
        sigma_z: 1.0,
        level_b: 0,
        pad: [0; 2],
    };
    ctx.one_shot_passes("blur", |rec| {
        let b = &bufs;
        for (axis, input, output) in [
            (Axis::Horizontal, &b[1], &b[2]),
            (Axis::Vertical, &b[2], &b[3]),
        ] {
            let io = BlurIo {
                globals: &b[0],
                records: &b[4],
                keys: &b[5],
                input,
                output,
            };
            let shape = BlurShape {
                axis,
                semantic: false,
                radius: 2,
                half,
                size: (w, h),
                tiles: Tiles::All,
            };
            blur.record(rec, &shape, &io, &push)?;
        }
        Ok(())
    })
    .expect("run");
    let raw: Vec<u32> = bufs[3].download_pod(&ctx, 0, n as u64).expect("read");
    let out: Vec<f32> = raw
        .iter()
        .map(|v| (v & 0xFF) as f32 / 255.0 * ((v >> 8) & 0xFF) as f32 / 255.0)
        .collect();
    blur.destroy(&ctx);
    for b in &mut bufs {
        b.destroy(&ctx);
    }
    let col = |x: u32, src: &[f32]| -> Vec<f32> {
        (4..h - 4).map(|y| src[(y * w + x) as usize]).collect()
    };
    let mean = |v: &[f32]| v.iter().sum::<f32>() / v.len() as f32;
    let var = |v: &[f32]| {
        let m = mean(v);
        v.iter().map(|x| (x - m) * (x - m)).sum::<f32>() / v.len() as f32
    };
    let (edge_l, edge_r) = (mean(&col(w / 2 - 1, &out)), mean(&col(w / 2, &out)));
    eprintln!("half {half}: edge means after blur: left {edge_l:.3} right {edge_r:.3}");
    assert!(
        (edge_l - 0.2).abs() < 0.05 && (edge_r - 0.9).abs() < 0.05,
        "the blur bled across the depth edge"
    );
    let inner: Vec<f32> = (8..24).flat_map(|x| col(x, &out)).collect();
    let inner_before: Vec<f32> = (8..24).flat_map(|x| col(x, &amb)).collect();
    eprintln!(
        "flat-area variance {:.5} -> {:.5}",
        var(&inner_before),
        var(&inner)
    );
    assert!(
        var(&inner) < 0.3 * var(&inner_before),
        "the blur does not reduce noise on a flat area"
    );
    assert_no_validation_messages(&ctx);
}

#[test]
fn zooming_changes_the_semantic_level_through_a_blend() {
    let scene = scene::procedural("capsid", 20000, 2).expect("capsid");
    let (_, r) = scene.bounding_sphere();
    let full = 2.0 * r as f64 * 1.05;
    let mut seen = Vec::new();
    let mut blended = false;
    for i in 0..60 {
        let h = full * 0.93f64.powi(i);
        let cam = Camera::new(
            DVec3::ZERO,
            DVec3::new(0.0, 0.0, -1.0),
            DVec3::Y,
            h,
            None,
            64,
            64,
        )
        .expect("camera");
        let (levels, c) = level_choice(&scene, &cam, &None);
        assert!(
            levels.len() >= 3,
            "capsid should have several useful levels: {levels:?}"
        );
        if c.blend > 0.0 && c.blend < 1.0 {
            blended = true;
            assert_ne!(c.level_a, c.level_b);
        }
        if seen.last() != Some(&c.level_a) {
            seen.push(c.level_a);
        }
    }
    eprintln!("levels while zooming in: {seen:?}");
    assert!(
        seen.len() >= 3 && seen.windows(2).all(|w| w[1] > w[0]),
        "levels do not refine with zoom: {seen:?}"
    );
    assert!(blended, "no blended range between levels");
}

/// The half-resolution record ssdo_prep packs, read back and unpacked,
/// against the f64 ray caster at its representative pixel: view depth
/// within 1e-5 of the scene size, normal within 1e-3 rad (octahedral
/// snorm16), region hashes exact at both active levels, the representative
/// the first covered pixel of its block in the rotating order, reflected
/// light = albedo x max(N.L, 0) x key-light visibility within 8-bit steps,
/// and blocks without covered pixels marked background.
#[test]
fn packed_records_round_trip() {
    let ctx = validated_context();
    let mut scene = load_data("1tii.pdb");
    scene.spheres.truncate(2000);
    let cam = camera(&scene, 160, 120, None);
    let mut s = settings(cam, ShadowMode::Issm);
    s.ssdo = SsdoMode::Semantic;
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let records = r.inspect().read_records().expect("records");
    let shadow = r.inspect().read_shadow().expect("shadow");
    let choice = r.inspect().level_choice().expect("levels");
    drop(r);
    assert_no_validation_messages(&ctx);

    let (_, radius) = scene.bounding_sphere();
    let size = 2.0 * radius as f64;
    let img = sphereshade::reference::cast(&scene.spheres, &cam, 2e-5 * size);
    let (w, h) = (cam.width, cam.height);
    let (hw, hh) = (w.div_ceil(2), h.div_ceil(2));
    assert_eq!(records.len(), (hw * hh) as usize);
    let light = -DVec3::new(-1.0, -1.0, -1.0).normalize();
    let (mut checked, mut worst_z, mut worst_n, mut worst_rad) = (0, 0.0f64, 0.0f64, 0.0f64);
    let mut lit = 0;
    for by in 0..hh {
        for bx in 0..hw {
            let rec = &records[(by * hw + bx) as usize];
            // The rotating order of glsl/ssdo_prep.comp.
            let first = (bx + 2 * by) % 4;
            let covered = (0..4).map(|k| (first + k) % 4).find_map(|c| {
                let (x, y) = (2 * bx + c % 2, 2 * by + c / 2);
                let i = (y * w + x) as usize;
                (x < w && y < h && img.ids[i] != u32::MAX).then_some((c, x, y, i))
            });
            let Some((c, x, y, i)) = covered else {
                assert!(!rec.covered, "block ({bx},{by}) has no covered pixel");
                continue;
            };
            if (0..4).any(|k| {
                let (x, y) = (2 * bx + k % 2, 2 * by + k / 2);
                x < w && y < h && img.ambiguous[(y * w + x) as usize]
            }) {
                continue; // f32 may legitimately see another sphere here
            }
            assert!(rec.covered, "block ({bx},{by})");
            assert_eq!(rec.sub, [c % 2, c / 2], "block ({bx},{by})");
            let sp = &scene.spheres[img.ids[i] as usize];
            let centre = DVec3::from(sp.center.map(|v| v as f64));
            let (o, d) = cam.ray(x, y);
            let p = o + img.t[i] * d;
            let z = (p - cam.center).dot(cam.dir);
            worst_z = worst_z.max((rec.z as f64 - z).abs() / size);
            let n = (p - centre).normalize();
            let rn = DVec3::from(rec.normal.map(|v| v as f64));
            worst_n = worst_n.max(rn.normalize().dot(n).clamp(-1.0, 1.0).acos());
            use sphereshade::stages::ssdo::record::region_hash;
            assert_eq!(
                rec.region_a,
                region_hash(sp.region[choice.level_a as usize])
            );
            assert_eq!(
                rec.region_b,
                region_hash(sp.region[choice.level_b as usize])
            );
            // Reflected key light, linear albedo (sRGB 2.2) as the shader.
            // The record's visibility is the shadow AOV's where the point
            // faces the light; where it faces away (up to rounding at the
            // terminator) the ISSM lookup of the records may count the
            // point's own sphere (glsl/lookup_issm.glsl, ISSM_SELF_TEST),
            // which the reflected light multiplies by max(N.L, 0) = 0.
            let vis = shadow[i] as f64;
            if n.dot(light) > 1e-3 {
                assert!(
                    (rec.visibility as f64 - vis).abs() <= 1.0 / 255.0 + 1e-6,
                    "block ({bx},{by}): record visibility {} against the shadow AOV's {vis}",
                    rec.visibility
                );
                lit += 1;
            }
            for k in 0..3 {
                let albedo = (sp.color[k] as f64 / 255.0).powf(2.2);
                let want = albedo * n.dot(light).max(0.0) * vis;
                worst_rad = worst_rad.max((rec.radiance[k] as f64 - want).abs());
            }
            checked += 1;
        }
    }
    eprintln!(
        "{checked} records: worst depth error {worst_z:.2e} of the scene size, normal {worst_n:.2e} rad, \
         radiance {worst_rad:.4}"
    );
    assert!(checked > 500, "too few covered blocks: {checked}");
    assert!(lit > 200, "too few blocks facing the light: {lit}");
    assert!(worst_z < 1e-5, "depth error {worst_z:.2e}");
    assert!(worst_n < 1e-3, "normal error {worst_n:.2e} rad");
    assert!(worst_rad <= 1.5 / 255.0, "radiance error {worst_rad:.4}");
}
