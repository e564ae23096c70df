# SPDX-License-Identifier: GPL-2.0-or-later
"""What a saved .blend keeps of the Crisp panel means the same to a later add-on and library. Blender
stores an enum as a number: the method menu's items (the library's list of filters) carry fixed numbers
(properties.METHOD_NUMBERS), so a method added to the library or moved in its list does not change a
saved scene's method. Without them the number was the item's position, and a file's phlm became
taa-improved when taa-improved was put before it."""

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


if __name__ == "__main__":
    harness.run(SavedMethodTest)
