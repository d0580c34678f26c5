//! SSDO against a ray-traced ambient-occlusion reference (f64, 256
//! cosine-weighted rays per pixel within the SSDO's far radius, every
//! sphere tested): the rank correlation (Spearman) of the `ao` AOV with the
//! reference over covered pixels, on the first 2,500 atoms of 1TII at 320x240.

mod common;

use common::*;
use sphereshade::reference::{ambient_occlusion, spearman};
use sphereshade::render::Renderer;
use sphereshade::settings::{ShadowMode, SsdoMode};

fn correlation(mode: SsdoMode) -> (f64, usize) {
    let ctx = validated_context();
    let mut scene = load_data("1tii.pdb");
    scene.spheres.truncate(2500);
    let cam = camera(&scene, 320, 240, None);
    let mut s = settings(cam, ShadowMode::None);
    s.ssdo = mode;
    s.blur = true;
    let mut r = Renderer::new(&ctx, &scene, s).expect("renderer");
    r.render_frame().expect("frame");
    let radius = r.ssdo_far_radius();
    let ao: Vec<f32> = r.read_ambient().expect("ao").iter().map(|a| a[0]).collect();
    drop(r);
    assert_no_validation_messages(&ctx);
    let reference = ambient_occlusion(&scene.spheres, &cam, radius, 256, 2);
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for (i, v) in reference.iter().enumerate() {
        if let Some(v) = v {
            a.push(*v);
            b.push(ao[i] as f64);
        }
    }
    (spearman(&a, &b), a.len())
}

#[test]
fn plain_ssdo_ranks_like_ray_traced_ao() {
    let (rho, n) = correlation(SsdoMode::Plain);
    eprintln!("plain SSDO vs ray-traced AO: Spearman {rho:.3} over {n} pixels");
    assert!(n > 3000, "too few covered pixels: {n}");
    assert!(rho >= 0.85, "plain SSDO rank correlation {rho:.3} < 0.85");
}
