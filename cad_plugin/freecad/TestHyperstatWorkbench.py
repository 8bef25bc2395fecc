"""Unit tests of the Hyperstat workbench, run inside FreeCAD: ``freecadcmd -t TestHyperstatWorkbench``.

Units: lengths in mm, angles in rad.

Registered in ``Init.py`` (``FreeCAD.__unit_test__``), so the Test workbench lists
them too.  They use the real ``hyperstat`` command line (found as the workbench
finds it) and the real FreeCAD document machinery; ``freecadcmd -t`` exits 1 when
one fails.  The per-template checks (all six templates, classes and colours
against the solver, save and reopen) are in the project's pytest suite
(``tests/cad_plugin/freecad/``), which runs FreeCAD as a subprocess.
"""

import json
import math
import os
import tempfile
import unittest
from pathlib import Path

import FreeCAD

import hyperstat_freecad as hs


def _distance(a, b) -> float:
    pa, pb = a.getGlobalPlacement().Base, b.getGlobalPlacement().Base
    return (pa - pb).Length


class TestPackaging(unittest.TestCase):
    def test_package_xml_declares_the_workbench(self):
        meta = FreeCAD.Metadata(str(Path(hs.__file__).resolve().parent.parent / "package.xml"))
        self.assertEqual(meta.Name, "Hyperstat")
        self.assertTrue(meta.supportsCurrentFreeCAD())
        workbenches = meta.Content["workbench"]
        self.assertEqual([w.Classname for w in workbenches], ["HyperstatWorkbench"])

    def test_every_command_icon_exists(self):
        icons = Path(hs.__file__).resolve().parent.parent / "Resources" / "icons"
        for name in ("hyperstat", "insert", "parameters", "rebuild", "analyze", "results", "identify", "diagnose",
                     "report", "controller"):
            self.assertTrue((icons / f"{name}.svg").is_file(), name)


class TestCommandLine(unittest.TestCase):
    def test_the_command_line_is_found(self):
        self.assertTrue(os.access(hs.find_cli(), os.X_OK))

    def test_a_missing_sub_command_is_named(self):
        with self.assertRaises(hs.CommandMissing) as ctx:
            hs.run_cli(["frobnicate"])
        self.assertIn("'frobnicate'", str(ctx.exception))

    def test_a_wrong_HYPERSTAT_CLI_is_named(self):
        old = os.environ.get("HYPERSTAT_CLI")
        os.environ["HYPERSTAT_CLI"] = "/nonexistent/hyperstat"
        try:
            with self.assertRaises(hs.HyperstatWorkbenchError) as ctx:
                hs.find_cli()
            self.assertIn("HYPERSTAT_CLI", str(ctx.exception))
            self.assertIn("/nonexistent/hyperstat", str(ctx.exception))
        finally:
            if old is None:
                os.environ.pop("HYPERSTAT_CLI")
            else:
                os.environ["HYPERSTAT_CLI"] = old


class TestSkeleton(unittest.TestCase):
    """Slider-crank (paper 1, 4.1): spreadsheet-driven rebuild, bad values, measurements, exports."""

    @classmethod
    def setUpClass(cls):
        cls.doc = FreeCAD.newDocument("HyperstatUnitTest")
        cls.sk = hs.insert_skeleton(cls.doc, "slider_crank")
        cls.tmp = tempfile.mkdtemp(prefix="hyperstat-fc-test-")

    @classmethod
    def tearDownClass(cls):
        FreeCAD.closeDocument(cls.doc.Name)

    def test_1_unknown_template_and_parameter_leave_nothing_behind(self):
        n = len(self.doc.Objects)
        with self.assertRaises(hs.HyperstatWorkbenchError) as ctx:
            hs.insert_skeleton(self.doc, "no_such_template")
        self.assertIn("no_such_template", str(ctx.exception))
        with self.assertRaises(hs.HyperstatWorkbenchError) as ctx:
            hs.insert_skeleton(self.doc, "slider_crank", {"L9": 1.0})
        self.assertIn("'L9'", str(ctx.exception))
        self.assertEqual(len(self.doc.Objects), n)

    def test_2_spreadsheet_drives_the_rebuild(self):
        sk = self.sk
        sheet = sk.Spreadsheet
        # 'L1' reads as a cell address, so its alias is 'L1_'
        self.assertIn(("L1", f"{sheet.Name}.L1_"), sk.ExpressionEngine)
        sheet.set(sheet.getCellFromAlias("L1_"), "=55 mm")
        self.doc.recompute()
        self.assertAlmostEqual(sk.L1.Value, 55.0, places=12)
        self.assertTrue(sk.Status.startswith("outdated"))
        self.assertTrue(hs.needs_rebuild(sk))
        analysis = hs.analyze(sk)  # rebuilds first
        self.assertEqual(json.loads(sk.BuiltParameters)["L1"], 55.0)
        # the crank pin marker (joint 2) sits L1 from the crank pivot (joint 1), paper 1 Table 1: A2 = L1
        m = hs.markers(sk)
        self.assertAlmostEqual(_distance(m["m_1"], m["m_2"]), 55.0, places=6)
        self.assertEqual(sk.Status, "analysed")
        self.assertEqual(set(hs.class_spheres(sk)), set(hs.element_classes(analysis)[0]))
        self.assertEqual(dict(sk.ToleranceCounts), {k: str(v) for k, v in hs.tolerances(sk)["counts"].items()})
        # an angle goes to hyperstat in rad and comes back as FreeCAD degrees
        self.assertAlmostEqual(hs.current_parameters(sk)["home_angle"], math.pi / 3, places=12)

    def test_3_a_bad_value_is_one_clear_error_and_keeps_the_model(self):
        sk = self.sk
        m = hs.markers(sk)
        before = _distance(m["m_1"], m["m_2"])
        hs.set_parameters(sk, {"L2": 30.0})  # the rod must be longer than the crank
        with self.assertRaises(hs.HyperstatWorkbenchError) as ctx:
            hs.rebuild(sk)
        self.assertIn("'L2'", str(ctx.exception))
        self.assertTrue(sk.Status.startswith("error:"))
        self.assertEqual(_distance(hs.markers(sk)["m_1"], hs.markers(sk)["m_2"]), before)
        hs.set_parameters(sk, {"L2": 120.0})
        self.assertFalse(hs.needs_rebuild(sk))  # back to the parameters of the last build

    def test_4_identify_then_the_commands_of_other_issues(self):
        sk = self.sk
        model = hs.operations._model_file(sk)
        data = Path(self.tmp) / "sc.csv"
        hs.run_cli(["simulate", str(model), "--poses", "30", "--validation", "10", "--out", str(data), "--quiet"])
        validation = data.with_name("sc.validation.csv")
        result = hs.identify(sk, data, validation)
        self.assertEqual(result["mechanism"], "slider_crank")
        self.assertEqual(json.loads(sk.Identification)["rank"], result["rank"])
        self.assertIn("validation", sk.IdentificationText)
        for command, run, check in (
            ("diagnose", lambda: hs.diagnose(sk), lambda out: self.assertIn("gap_significant", out)),
            ("report", lambda: hs.export_report(sk, Path(self.tmp) / "report"),
             lambda out: self.assertTrue((out / "report.html").is_file())),
            ("export-controller", lambda: hs.export_controller(sk, Path(self.tmp) / "machine.json"),
             lambda out: self.assertTrue(out.is_file())),
        ):
            try:
                out = run()
            except hs.CommandMissing as exc:  # being built in parallel: absent is told clearly
                self.assertIn(f"'{command}'", str(exc))
            else:
                check(out)

    def test_5_missing_measurements_are_named(self):
        with self.assertRaises(hs.HyperstatWorkbenchError) as ctx:
            hs.identify(self.sk, "/nonexistent/data.csv")
        self.assertIn("/nonexistent/data.csv", str(ctx.exception))
        self.assertNotEqual(self.sk.MeasurementFile, "/nonexistent/data.csv")

