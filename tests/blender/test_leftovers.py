# SPDX-License-Identifier: GPL-2.0-or-later
"""What a run leaves behind in a long Blender session (a studio renders shot after shot in one): the
library's handles (every crispNew* released, counted at native.call), also of what fails part-way."""

import collections
import os
import sys
import unittest

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

import crisp  # noqa: E402
from crisp import native  # noqa: E402

LIB_OK, LIB_WHY = harness.library_usable()
PAIRS = (("crispNewContext", "crispReleaseContext"), ("crispNewFilter", "crispReleaseFilter"),
         ("crispLoadFrame", "crispReleaseFrame"))


@unittest.skipUnless(LIB_OK, "library not usable: " + LIB_WHY)
class LeftoverTest(unittest.TestCase):
    def setUp(self):
        crisp.register()
        self.addCleanup(crisp.unregister)
        self.calls = collections.Counter()
        real = native.call

        def counted(name, *args):
            self.calls[name] += 1
            return real(name, *args)
        native.call = counted
        self.addCleanup(setattr, native, "call", real)

    def live_handles(self):
        """{what: made and not released} of the library's contexts, filters and frames."""
        return {new: self.calls[new] - self.calls[release] for new, release in PAIRS
                if self.calls[new] != self.calls[release]}

    def test_a_frame_filter_refusing_its_parameters_releases_what_it_made(self):
        """FrameFilter with a value the library refuses raises, and leaves no context or filter behind."""
        for _ in range(2):
            with self.assertRaises(native.CrispError):
                native.FrameFilter("taa", {"sharpen": 1e9})
        self.assertEqual(self.live_handles(), {})


if __name__ == "__main__":
    harness.run(LeftoverTest)
