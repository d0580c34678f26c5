//! Proves the validation setup works: a deliberately broken shader that
//! stores out of bounds must be reported by GPU-assisted validation, and the
//! layout probe shows Rust and GLSL agree on every shared struct field.

mod common;

use common::*;
use sphereshade::gpu::{Globals, SphereAttr};
use sphereshade::passes::spirv;
use sphereshade::vk::Grid;
use sphereshade::vk::pipeline::{PipelineDesc, ro, rw, uniform, wo};
use sphereshade::vk::{Buffer, ComputePipeline};

#[test]
fn out_of_bounds_store_is_reported_by_gpu_av() {
    let ctx = validated_context();
    let before = ctx.validation_messages();
    let mut p = ComputePipeline::new(
        &ctx,
        &PipelineDesc {
            name: "test oob",
            shader: spirv::TEST_OOB_COMP,
            bindings: &[rw("Out")],
            push_size: 4,
            local_size: 1,
            constants: &[],
            scene: 0,
        },
    )
    .expect("pipeline");
    let mut buf = Buffer::storage(&ctx, "oob target", 64).expect("buffer");
    ctx.one_shot_passes("oob", |rec| {
        rec.pass("oob", |pass| {
            pass.dispatch(&p, &16u32, Grid::Groups([1, 1, 1]), &[("Out", &buf)]);
            Ok(())
        })
    })
    .expect("dispatch");
    let after = ctx.validation_messages();
    let msgs = ctx.messages.messages().join("\n");
    buf.destroy(&ctx);
    p.destroy(&ctx);
    assert!(
        after > before,
        "GPU-assisted validation missed an out-of-bounds store"
    );
    assert!(
        msgs.contains("02706") || msgs.to_lowercase().contains("out of bounds"),
        "unexpected message: {msgs}"
    );
}

const BASE: u32 = 0x4000_0000;

#[test]
fn gpu_struct_layout_matches_glsl() {
    let ctx = validated_context();
    // Every 32-bit word gets a distinct value; the probe copies fields in
    // declaration order, so the output must be BASE, BASE+1, ... exactly.
    // BASE makes every word a normal float (denormals may be flushed).
    let gwords = std::mem::size_of::<Globals>() / 4;
    let mut globals = Globals::default();
    for (i, w) in bytemuck::cast_slice_mut::<Globals, u32>(std::slice::from_mut(&mut globals))
        .iter_mut()
        .enumerate()
    {
        *w = BASE + i as u32;
    }
    let mut attrs = [SphereAttr::default(); 2];
    for (i, w) in bytemuck::cast_slice_mut::<SphereAttr, u32>(&mut attrs)
        .iter_mut()
        .enumerate()
    {
        *w = BASE + (gwords + i) as u32;
    }
    let total = gwords + 2 * std::mem::size_of::<SphereAttr>() / 4;
    let mut gbuf = Buffer::new(
        &ctx,
        "probe globals",
        std::mem::size_of::<Globals>() as u64,
        ash::vk::BufferUsageFlags::UNIFORM_BUFFER,
        gpu_allocator::MemoryLocation::GpuOnly,
    )
    .expect("globals");
    gbuf.upload(&ctx, 0, bytemuck::bytes_of(&globals))
        .expect("upload");
    let mut abuf = Buffer::storage(&ctx, "probe attrs", 64).expect("attrs");
    abuf.upload(&ctx, 0, bytemuck::cast_slice(&attrs))
        .expect("upload");
    let mut out = Buffer::storage(&ctx, "probe out", (total * 4) as u64).expect("out");
    let mut p = ComputePipeline::new(
        &ctx,
        &PipelineDesc {
            name: "layout probe",
            shader: spirv::LAYOUT_PROBE_COMP,
            bindings: &[uniform("GlobalsBlock"), ro("Attrs"), wo("Out")],
            push_size: 0,
            local_size: 1,
            constants: &[],
            scene: 0,
        },
    )
    .expect("pipeline");
    ctx.one_shot_passes("probe", |rec| {
        rec.pass("probe", |pass| {
            pass.dispatch(
                &p,
                &(),
                Grid::Groups([1, 1, 1]),
                &[("GlobalsBlock", &gbuf), ("Attrs", &abuf), ("Out", &out)],
            );
            Ok(())
        })
    })
    .expect("run");
    let words: Vec<u32> = out.download_pod(&ctx, 0, total as u64).expect("read");
    let expected: Vec<u32> = (0..total as u32).map(|i| BASE + i).collect();
    p.destroy(&ctx);
    for b in [&mut gbuf, &mut abuf, &mut out] {
        b.destroy(&ctx);
    }
    assert_eq!(
        words, expected,
        "GLSL and Rust disagree on a shared struct layout"
    );
    assert_no_validation_messages(&ctx);
}

/// Tearing down a renderer with every technique leaves nothing behind: the
/// layer reports leaked objects when the device is destroyed, and
/// `Context::finish` counts those too (the context's kept pipelines
/// included). A renderer like an earlier one on the same context takes
/// that one's pipelines (none compiled again) and draws the same image;
/// another technique adds its own.
#[test]
fn renderer_teardown_leaks_nothing() {
    use sphereshade::render::Renderer;
    use sphereshade::settings::{ShadowMode, SsdoMode};
    let ctx = validated_context();
    let s = sphereshade::scene::procedural("capsid", 1500, 4).expect("scene");
    // (pipelines compiled on the context after each renderer)
    let mut kept = Vec::new();
    let mut images = Vec::new();
    for (shadows, ssdo) in [
        (ShadowMode::IssmSoft, SsdoMode::Semantic),
        (ShadowMode::IssmSoft, SsdoMode::Semantic),
        (ShadowMode::Deep, SsdoMode::Plain),
        (ShadowMode::None, SsdoMode::Off),
    ] {
        let mut st = settings(camera(&s, 64, 48, None), shadows);
        st.ssdo = ssdo;
        st.ssdo_knobs.blur = true;
        let mut r = Renderer::new(&ctx, &s, st).expect("renderer");
        r.render_frame().expect("frame");
        kept.push(ctx.pipelines_compiled());
        images.push(r.inspect().read_color().expect("colour"));
    }
    assert!(kept[0] > 0 && kept[1] == kept[0], "kept {kept:?}");
    assert!(
        kept[2] > kept[1],
        "deep lists and plain SSDO: kept {kept:?}"
    );
    assert!(images[1] == images[0], "the same settings, another image");
    assert!(images[2] != images[0], "the techniques drew the same image");
    let (n, msgs) = ctx.finish();
    assert_eq!(n, 0, "teardown reported: {}", msgs.join("\n---\n"));
}

/// Negative: a buffer that is never destroyed must show up as a leak.
#[test]
fn a_leaked_buffer_is_reported_at_teardown() {
    let ctx = validated_context();
    let b = Buffer::storage(&ctx, "deliberately leaked", 256).expect("buffer");
    std::mem::forget(b);
    let (n, msgs) = ctx.finish();
    assert!(n > 0, "a leaked VkBuffer went unreported");
    let all = msgs.join("\n");
    assert!(
        all.contains("deliberately leaked") || all.contains("VkBuffer"),
        "unexpected messages: {all}"
    );
}

/// A scene table the shaders only read as texels is bounded by the texel
/// limit, not the storage range (an instanced scene's batch table passes
/// lavapipe's 128 MiB past 10^9 atoms): one a little over the range is
/// made, filled in pieces and read back; a storage buffer of that size is
/// refused with a one-line error naming it and the limit.
#[test]
fn read_only_tables_pass_the_storage_range() {
    let ctx = validated_context();
    let range = ctx.props.limits.max_storage_buffer_range as u64;
    let texels = ctx.props.limits.max_texel_buffer_elements as u64;
    let size = range + (5 << 20) + 12;
    assert!(
        size / 4 <= texels,
        "the device's texel limit is below its storage range"
    );
    let err = Buffer::storage(&ctx, "too large storage", size)
        .err()
        .expect("a storage buffer past the range must be refused")
        .to_string();
    assert!(
        err.contains("too large storage") && err.contains("maxStorageBufferRange"),
        "{err}"
    );
    let mut table = Buffer::table(&ctx, "large table", size).expect("table");
    table
        .view(&ctx, ash::vk::Format::R32_UINT)
        .expect("a texel view of the whole table");
    let words: Vec<u32> = (0..size / 4)
        .map(|i| (i as u32).wrapping_mul(2654435761))
        .collect();
    table
        .upload(&ctx, 0, bytemuck::cast_slice(&words))
        .expect("upload in pieces");
    // the ends of the first and last pieces, and the tail
    for first in [0, (32 << 20) / 4 - 2, size / 4 - 3] {
        let got: Vec<u32> = table.download_pod(&ctx, first, 3).expect("download");
        assert_eq!(
            got,
            words[first as usize..first as usize + 3],
            "at word {first}"
        );
    }
    table.destroy(&ctx);
    let (n, msgs) = ctx.finish();
    assert_eq!(n, 0, "{}", msgs.join("\n---\n"));
}

/// Declared bindings are checked against the shader's SPIR-V at pipeline
/// creation: a wrong access qualifier, a missing, an extra or a misnamed
/// binding and a wrong push-constant size are each an error that names the
/// shader, the binding and both types. Dispatches bind by name.
#[test]
fn binding_mismatches_are_rejected_with_the_shader_and_binding_named() {
    let ctx = validated_context();
    let good = [
        uniform("GlobalsBlock"),
        rw("Texels"),
        wo("Tiles"),
        rw("Counters"),
    ];
    let make = |bindings: &[sphereshade::vk::pipeline::Binding], push: u32| {
        ComputePipeline::new(
            &ctx,
            &PipelineDesc {
                name: "mismatch probe",
                shader: spirv::DEEP_ALLOC_COMP,
                bindings,
                push_size: push,
                local_size: 64,
                constants: &[],
                scene: 0,
            },
        )
    };
    let mut ok = make(&good, 4).expect("the correct declaration is accepted");
    // A dispatch naming a binding the pipeline lacks, or missing one, fails.
    let buf = Buffer::storage(&ctx, "probe", 64).expect("buffer");
    let err = ok
        .uses(&[("Texels", &buf), ("Nope", &buf)])
        .expect_err("unknown binding name");
    assert!(err.to_string().contains("'Nope'"), "{err}");
    let err = ok.uses(&[("Texels", &buf)]).expect_err("missing bindings");
    assert!(err.to_string().contains("no buffer given"), "{err}");
    ok.destroy(&ctx);
    ok.destroy(&ctx); // idempotent

    let mut swapped = good;
    swapped[1] = ro("Texels");
    let mut missing = good.to_vec();
    missing.remove(2);
    let mut renamed = good;
    renamed[3] = rw("Counter");
    let mut extra = good.to_vec();
    extra.push(ro("Shadow"));
    for (bindings, push, needles) in [
        (
            swapped.to_vec(),
            4,
            vec![
                "deep_alloc.comp",
                "'Texels'",
                "read-write storage buffer",
                "readonly",
            ],
        ),
        (
            missing,
            4,
            vec!["deep_alloc.comp", "'Tiles'", "not declared"],
        ),
        (
            renamed.to_vec(),
            4,
            vec!["deep_alloc.comp", "'Counters'", "not declared"],
        ),
        (
            extra,
            4,
            vec!["deep_alloc.comp", "'Shadow'", "does not have"],
        ),
        (
            good.to_vec(),
            16,
            vec!["deep_alloc.comp", "push constants", "16"],
        ),
    ] {
        // A binding the shader lacks is an error only where shaders keep
        // every binding (debug builds: src/vk/pipeline.rs `strict`); an
        // optimised build may have dropped an unused one.
        if !cfg!(debug_assertions) && bindings.len() > good.len() {
            let mut p = make(&bindings, push).expect("accepted when optimised");
            p.destroy(&ctx);
            continue;
        }
        let err = make(&bindings, push)
            .err()
            .unwrap_or_else(|| panic!("{bindings:?} push {push} was accepted"));
        let msg = err.to_string();
        for n in needles {
            assert!(msg.contains(n), "'{n}' missing from: {msg}");
        }
        eprintln!("rejected: {msg}");
    }
    let mut buf = buf;
    buf.destroy(&ctx);
    assert_no_validation_messages(&ctx);
}
