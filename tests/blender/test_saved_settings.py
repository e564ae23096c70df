# SPDX-License-Identifier: GPL-2.0-or-later
"""What a saved .blend keeps of the Crisp panel means the same to a later add-on and library. Blender
stores an enum as a number: the method menu's items (the library's list of filters) carry fixed numbers
(properties.METHOD_NUMBERS), so a method added to the library or moved in its list does not change a
saved scene's method. Without them the number was the item's position, and a file's phlm became
taa-improved when taa-improved was put before it. The choices of the methods' string parameters (taa's
clipSpace, phlm's modelFetch, ...) carry fixed numbers too (properties.CHOICE_NUMBERS)."""

import copy
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import bpy  # noqa: E402
import crisp  # noqa: E402
from crisp import native, plan, properties  # noqa: E402

# The library's list of filters when these numbers were fixed (native/core/registry.cpp): the
# positions files saved since then hold.
SAVED_ORDER = ["none", "fxaa", "repair", "taa", "taa-improved", "phlm", "rsaa"]
REAL_FILTER_TYPES = native.filter_types
# The choices of the library's string parameters when their numbers were fixed (the "a|b|c" of
# native/filters/*.cpp, native/temporal/jitter.cpp): the positions files saved since then hold.
_TAA = {"jitterWeighting": ["none", "blackman-harris"], "unjitter": ["blackman-harris", "nearest", "none"],
        "historyFilter": ["catmull-rom", "bilinear"], "clipSpace": ["rgb", "ycocg"]}
SAVED_CHOICES = {
    "repair": {"mask": ["gauss5", "box3"], "angleEstimator": ["regression", "thesis"]},
    "taa": _TAA,
    "taa-improved": _TAA,
    "phlm": {"jitterWeighting": ["none", "blackman-harris"], "unjitter": ["blackman-harris", "nearest", "none"],
             "modelFetch": ["catmull-rom", "bilinear", "nearest"]},
    "rsaa": {"verification": ["halve", "reassign", "none"], "textureAA": ["fxaa", "none"]},
}
REAL_FILTER_INFO = native.filter_info


class SavedMethodTest(unittest.TestCase):
    def setUp(self):
        harness.library_usable()  # the library when there is one; the static list otherwise
        crisp.register()
        self.addCleanup(crisp.unregister)
        self.scene = bpy.context.scene

    def use_list(self, names):
        """The method menu as a library with this list of filters gives it (names None: no library,
        the add-on's own list)."""
        def filter_types():
            if names is None:
                raise native.CrispError("no library")
            return list(names)
        native.filter_types = filter_types

    def tearDown(self):
        native.filter_types = REAL_FILTER_TYPES

    def test_every_method_has_its_own_number(self):
        self.assertEqual(sorted(properties.METHOD_NUMBERS), sorted(plan.METHOD_PASSES))
        self.assertEqual(len(set(properties.METHOD_NUMBERS.values())), len(properties.METHOD_NUMBERS))
        # A method of a newer library this add-on does not know gets a number none of its own take.
        self.assertNotIn(properties.method_number("future-aa"), properties.METHOD_NUMBERS.values())

    def test_a_saved_number_keeps_its_method(self):
        """A file saved with the list as it is holds each method's position in it: the same method."""
        for number, name in enumerate(SAVED_ORDER):
            self.scene.crisp["method"] = number  # as the .blend holds it
            self.assertEqual(self.scene.crisp.method, name)
            self.scene.crisp.method = name
            self.assertEqual(self.scene.crisp["method"], number)
        for number, name in enumerate(["blackman-harris", "uniform"]):  # the Jitter menu's, fixed too
            self.scene.crisp["jitter_distribution"] = number
            self.assertEqual(self.scene.crisp.jitter_distribution, name)
        for number, name in enumerate(["none", "piz", "zip"]):  # the Input Codec menu's, fixed too
            self.scene.crisp["input_codec"] = number
            self.assertEqual(self.scene.crisp.input_codec, name)

    def test_a_method_added_or_moved_in_the_library_does_not_change_a_saved_scene(self):
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "shot.blend")
            for name in SAVED_ORDER:
                native.filter_types = REAL_FILTER_TYPES
                bpy.context.scene.crisp.method = name
                bpy.ops.wm.save_as_mainfile(filepath=path)
                for names in (["future-aa"] + SAVED_ORDER,  # a method put first
                              list(reversed(SAVED_ORDER)),  # the list reordered
                              ["none", "fxaa", "taa", "phlm", "rsaa", "repair", "taa-improved"],
                              None):  # no library: the add-on's own list
                    self.use_list(names)
                    bpy.ops.wm.open_mainfile(filepath=path)
                    self.assertEqual(bpy.context.scene.crisp.method, name, names)


def library_choices():
    """{(method, parameter): [choices]} of the loaded library's string parameters, as it lists them."""
    return {(m, p["name"]): list(p["choices"]) for m in REAL_FILTER_TYPES()
            for p in REAL_FILTER_INFO(m)["params"] if p.get("choices")}


@unittest.skipUnless(harness.library_usable()[0], "libcrisp not built")
class SavedChoiceTest(unittest.TestCase):
    """The same for the methods' parameters with a list of choices: their menus are built at registration
    from the library's tables, so a library whose list has a choice added or moved is the add-on
    registered again with that library's tables."""

    def setUp(self):
        crisp.register()
        self.addCleanup(crisp.unregister)
        s = bpy.context.scene.crisp  # the file another test opened: its choices back to the defaults
        for method, param in library_choices():
            properties.param_group(s, method).property_unset(param)

    def tearDown(self):
        native.filter_info = REAL_FILTER_INFO

    def use_choices(self, change):
        """The add-on registered again as with a library whose choice lists are change(method, parameter,
        choices) of the real ones (its first choice its default, as the library's tables have it)."""
        def filter_info(method):
            info = copy.deepcopy(REAL_FILTER_INFO(method))
            for p in info["params"]:
                if p.get("choices"):
                    p["choices"] = change(method, p["name"], list(p["choices"]))
                    p["default"] = p["choices"][0]
            return info
        crisp.unregister()
        native.filter_info = filter_info
        crisp.register()

    def reopen(self, path, change):
        self.use_choices(change)
        bpy.ops.wm.open_mainfile(filepath=path)
        return bpy.context.scene.crisp

    def test_every_choice_has_its_own_number(self):
        lists = library_choices()
        # The add-on's record is the lists files hold: never reordered, nor a choice added to it.
        self.assertEqual({(m, p): list(c) for m, ps in properties.CHOICE_NUMBERS.items() for p, c in ps.items()},
                         {(m, p): c for m, ps in SAVED_CHOICES.items() for p, c in ps.items()})
        for (method, param), choices in lists.items():
            numbers = properties.choice_numbers(method, param, choices)
            recorded = SAVED_CHOICES.get(method, {}).get(param, [])
            for choice in choices:  # its position in the record, or (a later library's) one from its name
                if choice in recorded:
                    self.assertEqual(numbers[choice], recorded.index(choice), (method, param, choice))
                else:
                    self.assertGreaterEqual(numbers[choice], 1000, (method, param, choice))
            # Choices of a newer library take numbers none of the recorded ones (nor each other) take,
            # the same wherever they sit in its list.
            more = properties.choice_numbers(method, param, ["future-b"] + choices + ["future-a"])
            self.assertEqual(len(set(more.values())), len(more), (method, param))
            self.assertTrue(all(more[c] >= 1000 for c in ("future-a", "future-b")))
            moved = ["future-a"] + choices[::-1] + ["future-b"]
            self.assertEqual(more, properties.choice_numbers(method, param, moved))
        # Two new names whose numbers from their names clash: the later in name order takes the next free one.
        real_name_number = properties.name_number
        properties.name_number = lambda name: 1000
        try:
            self.assertEqual(properties.choice_numbers("taa", "clipSpace", ["y", "rgb", "x"]),
                             {"rgb": 0, "x": 1000, "y": 1001})
        finally:
            properties.name_number = real_name_number

    def test_a_saved_number_keeps_its_choice(self):
        """A file saved with the lists as they are holds each choice's position in its list."""
        s = bpy.context.scene.crisp
        for method, params in SAVED_CHOICES.items():
            group = properties.param_group(s, method)
            for param, choices in params.items():
                for number, choice in enumerate(choices):
                    group[param] = number  # as the .blend holds it
                    self.assertEqual(getattr(group, param), choice, (method, param))
                    setattr(group, param, choice)
                    self.assertEqual(group[param], number, (method, param))

    def test_a_choice_added_or_moved_in_the_library_does_not_change_a_saved_scene(self):
        def set_all(pick):  # each parameter set to choices[pick] (or its last): none the default (the first)
            s = bpy.context.scene.crisp
            out = {}
            for (method, param), choices in library_choices().items():
                setattr(properties.param_group(s, method), param, choices[min(pick, len(choices) - 1)])
                out[(method, param)] = choices[min(pick, len(choices) - 1)]
            return out

        changes = [lambda m, p, c: ["future-" + p] + c,  # a choice put first (the library's new default)
                   lambda m, p, c: c[::-1],  # the list reordered
                   lambda m, p, c: c[1:] + ["future"] + c[:1]]  # rotated, with a choice in the middle
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "shot.blend")
            for pick in (1, 2):
                native.filter_info = REAL_FILTER_INFO
                crisp.unregister()
                crisp.register()
                saved = set_all(pick)
                bpy.ops.wm.save_as_mainfile(filepath=path)
                for n, change in enumerate(changes):
                    s = self.reopen(path, change)
                    for (method, param), choice in saved.items():
                        group = properties.param_group(s, method)
                        self.assertEqual(getattr(group, param), choice, (n, method, param))
                    # and sent to the library as saved (unless it is that library's default)
                    default = s.taa.bl_rna.properties["clipSpace"].default
                    self.assertEqual(properties.changed_params(s, "taa").get("clipSpace", default), "ycocg")

    def test_a_choice_the_library_dropped_is_refused_by_name_and_kept(self):
        """A saved choice the library no longer offers matches no item: Blender reads it "" (and the
        panel shows an empty menu). A run does not take another choice: the choice is sent by its name,
        which the library refuses before a frame is rendered; the file keeps its number, so a library
        that offers it again gives it back."""
        s = bpy.context.scene.crisp
        s.taa.clipSpace = "ycocg"
        s.phlm.modelFetch = "bilinear"
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "shot.blend")
            bpy.ops.wm.save_as_mainfile(filepath=path)
            dropped = {"clipSpace": "ycocg", "modelFetch": "bilinear"}
            s = self.reopen(path, lambda m, p, c: [x for x in c if x != dropped.get(p)])
            self.assertEqual(s.taa.clipSpace, "")
            self.assertEqual(properties.changed_params(s, "taa"), {"clipSpace": "ycocg"})
            self.assertEqual(properties.changed_params(s, "phlm"), {"modelFetch": "bilinear"})
            self.assertEqual(s.set_params_text(), "")  # method none
            s.method = "phlm"
            self.assertEqual(s.set_params_text(), "modelFetch=bilinear")
            s.taa.unjitter = "none"  # another parameter changed and the file saved again
            bpy.ops.wm.save_as_mainfile(filepath=path)
            s = self.reopen(path, lambda m, p, c: c)
            self.assertEqual((s.taa.clipSpace, s.taa.unjitter, s.phlm.modelFetch), ("ycocg", "none", "bilinear"))
            # A choice of a newer library, which this add-on cannot name: refused too, not replaced.
            s = self.reopen(path, lambda m, p, c: c + ["future"])
            s.taa.clipSpace = "future"
            bpy.ops.wm.save_as_mainfile(filepath=path)
            s = self.reopen(path, lambda m, p, c: c)
            self.assertEqual(s.taa.clipSpace, "")
            bad = native.check_params("taa", properties.changed_params(s, "taa"))
            self.assertIn("clipSpace", bad or "")
            # named as what it is: the refusal said "= '' is not one of"
            self.assertIn("'newer-crisp-choice-%d' is not one of"
                          % properties.name_number("future"), bad or "")
            s.method = "taa"  # one word, so the Flamenco job's `--set` text keeps it whole
            self.assertIn(" clipSpace=newer-crisp-choice-%d" % properties.name_number("future"), " " + s.set_params_text())

    def test_the_viewport_preview_sends_a_dropped_choice_by_its_name(self):
        """The viewport preview sends the scene's parameters as the renders do (properties.param_value): a
        saved choice the library no longer offers by its name, so the library's refusal the panel shows
        says which choice of which parameter is not offered ("parameter 'clipSpace' = 'ycocg' is not one
        of: rgb"). It sent "", and the panel read "= '' is not one of". (The preview draws only with a
        window; what it checks with the library is this.)"""
        from crisp import viewport
        s = bpy.context.scene.crisp
        s.taa.clipSpace, s.taa.historyFilter = "ycocg", "bilinear"
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "shot.blend")
            bpy.ops.wm.save_as_mainfile(filepath=path)
            s = self.reopen(path, lambda m, p, c: [x for x in c if x != "ycocg"])
        self.assertEqual(s.taa.clipSpace, "")
        sent = viewport._filter_params(bpy.context, "taa")
        self.assertEqual((sent["clipSpace"], sent["historyFilter"]), ("ycocg", "bilinear"))
        self.assertEqual(sent["clipSpace"], properties.changed_params(s, "taa")["clipSpace"])


if __name__ == "__main__":
    harness.run(SavedMethodTest, SavedChoiceTest)
