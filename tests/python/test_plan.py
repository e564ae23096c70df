# SPDX-License-Identifier: Apache-2.0
"""Plain-Python tests of the add-on's pass plan (addon/crisp/plan.py) and Cryptomatte hashing
(addon/crisp/hashing.py): no Blender needed."""

import os
import sys

import pytest

SOURCE = os.environ.get("CRISP_SOURCE_DIR") or os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(SOURCE, "addon", "crisp"))

import hashing  # noqa: E402
import plan  # noqa: E402


def facts(**kw):
    base = dict(frame_start=1, frame_end=10, visible_objects=["A", "B", "C"])
    base.update(kw)
    return plan.SceneFacts(**base)


def test_spatial_methods_read_colour_only_whatever_moves():
    for method in ("none", "fxaa", "repair"):
        p = plan.make_plan(method, facts(camera_moves=True, moving_objects=["A"]))
        assert p.passes == ["color"]
        assert not p.jitter
        assert p.render_flags() == ["use_pass_combined"]
        assert set(p.skipped) == {"depth", "normal", "motion", "id", "albedo", "subsamples"}


def test_static_scene_drops_motion_and_taa_depth():
    p = plan.make_plan("taa", facts())
    assert p.passes == ["color"]
    assert "nothing moves" in p.skipped["motion"]
    assert "depth" in p.skipped
    assert p.jitter  # temporal methods still need sub-pixel jitter to accumulate


def test_renderer_vector_pass_is_used_when_it_exists():
    p = plan.make_plan("phlm", facts(moving_objects=["A"], renderer_motion_pass=True))
    assert p.passes == ["color", "depth", "motion"]  # phlm also reads depth (disocclusion)
    assert p.motion_source == "renderer"
    assert "use_pass_vector" in p.render_flags()


def test_reconstruction_adds_depth_and_ids_only_when_needed():
    # object motion among several objects: depth + id
    p = plan.make_plan("phlm", facts(moving_objects=["B"]))
    assert p.passes == ["color", "depth", "motion", "id"]
    assert p.motion_source == "reconstruct"
    assert "use_pass_vector" not in p.render_flags()
    assert "Cryptomatte" in p.reasons["id"]
    # camera-only motion: depth, no id
    p = plan.make_plan("phlm", facts(camera_moves=True))
    assert p.passes == ["color", "depth", "motion"]
    assert "only the camera" in p.skipped["id"]
    # one visible object moving: no id
    p = plan.make_plan("taa", facts(moving_objects=["A"], visible_objects=["A"]))
    assert p.passes == ["color", "depth", "motion"]


def test_taa_improved_single_object_has_no_id():
    p = plan.make_plan("taa-improved", facts(visible_objects=["Cube"], moving_objects=["Cube"]))
    assert p.passes == ["color", "depth", "motion", "albedo"]
    assert "1 visible object" in p.skipped["id"]
    p = plan.make_plan("taa-improved", facts())
    assert p.passes == ["color", "depth", "id", "albedo"]


def test_rsaa_reads_geometry_and_subsamples():
    p = plan.make_plan("rsaa", facts(camera_moves=True))
    assert p.passes == ["color", "depth", "normal", "subsamples"]
    assert set(p.render_flags()) == {"use_pass_combined", "use_pass_z", "use_pass_normal"}


def test_temporal_error_reads_unjittered_geometry_only_where_something_moves():
    # Its warp and disocclusion test: motion, depth and IDs at the pixel centres (no jitter).
    p = plan.make_plan(plan.TEMPORAL_ERROR, facts(moving_objects=["B"]))
    assert p.passes == ["color", "depth", "motion", "id"] and not p.jitter
    assert p.motion_source == "reconstruct" and "pixel centres" in p.reasons["motion"]
    # camera-only motion: IDs still tell surfaces apart for the disocclusion test
    p = plan.make_plan(plan.TEMPORAL_ERROR, facts(camera_moves=True))
    assert p.passes == ["color", "depth", "motion", "id"]
    # one visible object: depth alone tells it from the background
    p = plan.make_plan(plan.TEMPORAL_ERROR, facts(moving_objects=["A"], visible_objects=["A"]))
    assert p.passes == ["color", "depth", "motion"]
    # the renderer's Vector pass: still depth and IDs, for the disocclusion test
    p = plan.make_plan(plan.TEMPORAL_ERROR, facts(camera_moves=True, renderer_motion_pass=True))
    assert p.passes == ["color", "depth", "motion", "id"] and p.motion_source == "renderer"
    # a still scene: W is the identity, nothing but colour
    p = plan.make_plan(plan.TEMPORAL_ERROR, facts())
    assert p.passes == ["color"] and "identity" in p.skipped["depth"]
    assert plan.TEMPORAL_ERROR not in plan.METHOD_PASSES  # not a method anyone can pick


def test_eval_render_sets_one_per_plan_and_the_warp_where_something_moves():
    def sets(methods, f):
        return plan.render_sets([plan.make_plan(m, f) for m in methods], f)
    # A still scene: colour-only methods need no render of their own (eevee_1 is theirs), no warp.
    assert sets(["none", "fxaa"], facts()) == {}
    s = sets(["none", "taa", "phlm"], facts())
    assert list(s) == ["jittered"] and s["jittered"].passes == ["color"] and s["jittered"].jitter
    assert s["jittered"].method == "taa+phlm"  # the same plan: one set
    # Moving: a set for each distinct plan, so no method is charged for passes another reads;
    # rsaa's geometry unjittered; and the warp's own set.
    s = sets(["none", "taa", "taa-improved", "rsaa"], facts(moving_objects=["B"]))
    assert set(s) == {"jittered-depth-motion-id", "jittered-depth-motion-id-albedo",
                      "unjittered-depth-normal-subsamples", "warp"}
    taa, improved = s["jittered-depth-motion-id"], s["jittered-depth-motion-id-albedo"]
    assert taa.passes == ["color", "depth", "motion", "id"] and taa.method == "taa" and taa.jitter
    assert improved.passes == ["color", "depth", "motion", "id", "albedo"] and improved.method == "taa-improved"
    assert improved.motion_source == "reconstruct" and "reprojects the history" in improved.reasons["motion"]
    rsaa = s["unjittered-depth-normal-subsamples"]
    assert rsaa.method == "rsaa" and not rsaa.jitter and "SADP" in rsaa.reasons["depth"]
    assert s["warp"].method == plan.TEMPORAL_ERROR and s["warp"].passes == ["color", "depth", "motion", "id"]
    # Each method's input set is the one named after its plan.
    for m in ("taa", "taa-improved", "rsaa"):
        p = plan.make_plan(m, facts(moving_objects=["B"]))
        assert s[plan.render_set_name(p)].passes == p.passes
    assert plan.render_set_name(plan.make_plan("fxaa", facts())) == "eevee_1"
    # Only colour-reading methods on a moving scene: the warp alone.
    assert list(sets(["none", "repair"], facts(camera_moves=True))) == ["warp"]
    for p in s.values():
        assert set(p.reasons) == set(p.passes) and p.passes == sorted(p.passes, key=plan.PASS_ORDER.index)


def test_a_deforming_object_alone_makes_the_scene_move():
    """Geometry that deforms (an armature, shape keys, time-reading Geometry Nodes) moves the scene
    though no object's transform does: the temporal methods get motion, and the IDs that motion
    reconstruction reads when several objects render."""
    for method in ("taa", "taa-improved", "phlm"):
        p = plan.make_plan(method, facts(deforming_objects=["B"]))
        assert "motion" in p.passes and "depth" in p.passes and "id" in p.passes, (method, p.passes)
        assert "B" in p.reasons["motion"], p.reasons["motion"]
        still = plan.make_plan(method, facts())
        assert "motion" not in still.passes, (method, still.passes)
    # One object that deforms: no other object to tell it from, so no ID pass for reconstruction.
    alone = plan.make_plan("taa", facts(deforming_objects=["A"], visible_objects=["A"]))
    assert "motion" in alone.passes and "id" not in alone.passes, alone.passes


def test_every_planned_pass_has_a_reason_and_json_round_trip():
    for method in list(plan.METHOD_PASSES) + [plan.TEMPORAL_ERROR]:
        for f in (facts(), facts(camera_moves=True), facts(moving_objects=["A"], deforming_objects=["B"])):
            p = plan.make_plan(method, f)
            assert set(p.reasons) == set(p.passes)
            assert all(p.reasons.values())
            assert not set(p.skipped) & set(p.passes)
            j = p.to_json()
            assert j["passes"] == p.passes and j["reasons"] == p.reasons
            assert method in p.describe()


def test_unknown_method_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown method 'smaa'"):
        plan.make_plan("smaa", facts())


def test_murmurhash3_known_values_and_cryptomatte_float_guard():
    # Published MurmurHash3_x86_32 test vectors (seed 0 and seed 1).
    assert hashing.murmurhash3_x86_32(b"") == 0
    assert hashing.murmurhash3_x86_32(b"", 1) == 0x514E28B7
    assert hashing.murmurhash3_x86_32(b"hello") == 0x248BFA47
    assert hashing.murmurhash3_x86_32(b"The quick brown fox jumps over the lazy dog") == 0x2E4FF723
    for name in ("Cube", "Sphere", "Wall", "a", "Ünïcode"):
        h = hashing.cryptomatte_hash(name)
        assert ((h >> 23) & 0xFF) not in (0, 255)
        assert hashing.cryptomatte_hex(name) == "%08x" % h


def test_an_image_that_changes_where_nothing_moves_is_not_averaged():
    """A keyed material (or light, or visibility) on a still scene: the passes stay those of a still scene
    (motion is zero), but the temporal methods must not average still pixels, and the plan says what
    changes; a spatial method is unaffected."""
    changing = facts(image_changes=["material 'Belt'"])
    for method in plan.TEMPORAL_METHODS:
        p = plan.make_plan(method, changing)
        assert not p.still_average and "material 'Belt'" in p.history_note, (method, p.history_note)
        assert "material 'Belt'" in p.skipped["motion"] and "history: " in p.describe()
        assert p.passes == plan.make_plan(method, facts()).passes
        assert plan.make_plan(method, facts()).still_average
    for method in ("fxaa", "rsaa", "none"):
        assert plan.make_plan(method, changing).still_average
    assert plan.make_plan("taa", changing).to_json()["still_average"] is False


def test_deforming_objects_are_not_said_to_be_reprojected_exactly():
    """Motion reconstruction is rigid (native/motion/reconstruct.h): the reason says so for what deforms,
    and names it apart from what moves; a renderer's Vector pass follows the deformation."""
    p = plan.make_plan("taa", facts(moving_objects=["A"], deforming_objects=["Sphere"]))
    reason = p.reasons["motion"]
    assert reason.startswith("A move and Sphere deforms:"), reason
    assert "rigidly" in reason and "trail" in reason, reason
    rendered = plan.make_plan("taa", facts(deforming_objects=["Sphere"], renderer_motion_pass=True))
    assert "rigidly" not in rendered.reasons["motion"]
    assert "rigidly" not in plan.make_plan("taa", facts(moving_objects=["A"])).reasons["motion"]
