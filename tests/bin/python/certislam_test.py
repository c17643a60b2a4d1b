"""The `certislam` Python module against the command and hand-built ground truth.

Run by CTest with /usr/bin/python3, PYTHONPATH at the built module, CERTISLAM_BINARY (the
command) and CERTISLAM_DATA_DIR (the shared real data) set.
"""
import json
import os
import subprocess
import tempfile
import unittest
from pathlib import Path

import numpy as np

import certislam

DATA = Path(os.environ.get("CERTISLAM_DATA_DIR", "")) / "g2o"
BINARY = os.environ.get("CERTISLAM_BINARY", "certislam")
COST_RELATIVE = 1e-9  # same library, same settings: the same cost up to printing
POSE_TOLERANCE = 1e-9
QUATERNION_ROUNDING = 2e-5  # 2 kQuaternionRounding (g2o_io.h): |q|^2 scales R


def cli_solve(path):
    out = subprocess.run([BINARY, "solve", str(path), "--json", "--quiet"],
                         capture_output=True, text=True, check=False)
    return json.loads(out.stdout)


def rot_z(angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def transform(R, t):
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = t
    return T


class SolveRealData(unittest.TestCase):
    def check_matches_cli(self, name):
        path = DATA / name
        solution = certislam.solve(path)
        cli = cli_solve(path)
        self.assertEqual(solution.certified, cli["certified"])
        self.assertEqual(solution.verdict, cli["verdict"])
        self.assertLessEqual(abs(solution.cost - cli["cost"]), COST_RELATIVE * abs(cli["cost"]))
        self.assertLessEqual(abs(solution.lower_bound - cli["lower_bound"]),
                             COST_RELATIVE * abs(cli["lower_bound"]))
        return solution

    def test_3d_file_certified_with_the_cost_of_the_command(self):
        solution = self.check_matches_cli("smallGrid3D.g2o")
        self.assertTrue(solution.certified)
        graph = certislam.read_g2o(DATA / "smallGrid3D.g2o")
        self.assertEqual(solution.poses.shape, (graph.n, 4, 4))
        np.testing.assert_allclose(solution.poses[:, 3, :], np.tile([0, 0, 0, 1], (graph.n, 1)))
        for R in solution.rotations[:10]:
            np.testing.assert_allclose(R.T @ R, np.eye(3), atol=1e-9)
        np.testing.assert_allclose(solution.translations, solution.poses[:, :3, 3])
        # The input's gauge: pose 0 where the file's VERTEX line puts it.
        np.testing.assert_allclose(solution.poses[0], graph.initial_guess[0], atol=1e-9)
        self.assertLessEqual(solution.lower_bound, solution.cost)
        self.assertLessEqual(solution.relative_bound, 1e-6)

    def test_2d_file_certified_with_the_cost_of_the_command(self):
        solution = self.check_matches_cli("intel.g2o")
        self.assertEqual(solution.poses.shape[1:], (3, 3))

    def test_certify_agrees_with_solve_and_refuses_the_initial_guess(self):
        graph = certislam.read_g2o(DATA / "smallGrid3D.g2o")
        solution = certislam.solve(graph)
        certificate = certislam.certify(graph, solution.poses)
        self.assertTrue(certificate.certified, certificate.verdict)
        self.assertLessEqual(abs(certificate.cost - solution.cost), 1e-9 * solution.cost)
        odometry = certislam.certify(graph, graph.initial_guess)
        self.assertFalse(odometry.certified)
        self.assertGreater(odometry.cost, solution.cost)


class InMemoryGraph(unittest.TestCase):
    def test_square_with_one_bent_edge_is_certified_below_the_exact_rotations_cost(self):
        # Four poses on a square, each turning 90 degrees; the last edge's translation is off
        # by e. With the rotations kept exact, the best translations share e equally over the
        # four edges: cost tau |e|^2 / 4, so f* is at most that (and above 0: the cycle is bent).
        tau, e = 100.0, np.array([0.0, 0.05, 0.0])
        graph = certislam.PoseGraph(3)
        step = transform(rot_z(np.pi / 2), [1.0, 0.0, 0.0])
        for i in range(4):
            T = step.copy()
            if i == 3:
                T[:3, 3] += e
            graph.add_edge(i, (i + 1) % 4, T, kappa=10.0, tau=tau)
        self.assertEqual((graph.n, graph.num_edges), (4, 4))
        solution = certislam.solve(graph)
        self.assertTrue(solution.certified, solution.reason)
        self.assertGreater(solution.cost, 0.0)
        self.assertLessEqual(solution.cost, tau * e @ e / 4 * (1 + 1e-9))
        self.assertLessEqual(solution.lower_bound, solution.cost)
        for i in range(3):
            relative = np.linalg.inv(solution.poses[i]) @ solution.poses[i + 1]
            np.testing.assert_allclose(relative, step, atol=np.linalg.norm(e))

    def test_bad_arrays_are_refused_by_name(self):
        graph = certislam.PoseGraph(3)
        with self.assertRaisesRegex(certislam.InputError, "shape"):
            graph.add_edge(0, 1, np.eye(3))
        with self.assertRaisesRegex(certislam.InputError, "SO\\(3\\)"):
            graph.add_edge(0, 1, 2.0 * np.eye(4))
        with self.assertRaises(ValueError):  # InputError is a ValueError
            certislam.PoseGraph(4)
        graph.add_edge(0, 2, np.eye(4))
        with self.assertRaisesRegex(certislam.InputError, "not connected"):
            certislam.solve(graph)


class G2oFiles(unittest.TestCase):
    def test_round_trip_keeps_edges_and_poses(self):
        graph = certislam.read_g2o(DATA / "tinyGrid3D.g2o")
        with tempfile.TemporaryDirectory() as tmp:
            certislam.write_g2o(Path(tmp) / "copy.g2o", graph)
            again = certislam.read_g2o(Path(tmp) / "copy.g2o")
        self.assertEqual((again.d, again.n, again.num_edges), (graph.d, graph.n, graph.num_edges))
        np.testing.assert_allclose(again.initial_guess, graph.initial_guess, atol=1e-12)
        a, b = graph.edges(), again.edges()
        np.testing.assert_array_equal(a["indices"], b["indices"])
        # The file's quaternions are used as written within 1e-5 of unit norm (read_g2o's rule)
        # and written back from the rotation they give: equal within that rounding.
        np.testing.assert_allclose(a["transforms"], b["transforms"], rtol=0, atol=QUATERNION_ROUNDING)
        for key in ("kappa", "tau"):
            np.testing.assert_allclose(a[key], b[key], rtol=1e-12)

    def test_round_trip_of_exact_rotations_is_exact(self):
        graph = certislam.PoseGraph(3)
        rng = np.random.default_rng(20261125)
        for i in range(5):
            q = rng.normal(size=4)
            q /= np.linalg.norm(q)
            w, x, y, z = q
            R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                          [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                          [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
            graph.add_edge(i, i + 1, transform(R, rng.normal(size=3)), kappa=1.0 + i, tau=3.0 + i)
        poses = np.tile(np.eye(4), (graph.n, 1, 1))
        with tempfile.TemporaryDirectory() as tmp:
            certislam.write_g2o(Path(tmp) / "exact.g2o", graph, poses)
            again = certislam.read_g2o(Path(tmp) / "exact.g2o")
        a, b = graph.edges(), again.edges()
        np.testing.assert_allclose(a["transforms"], b["transforms"], rtol=0, atol=1e-12)
        np.testing.assert_allclose(a["kappa"], b["kappa"], rtol=1e-12)
        np.testing.assert_allclose(again.initial_guess, poses, atol=1e-12)

    def test_bad_file_raises_naming_file_and_line(self):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "bad.g2o"
            path.write_text("# a comment\nVERTEX_SE2 0 0 0 0\nEDGE_SE2 0 1 1.0 oops 0 1 0 0 1 0 1\n")
            with self.assertRaisesRegex(certislam.InputError, "bad.g2o:3"):
                certislam.read_g2o(path)
            with self.assertRaisesRegex(certislam.InputError, "bad.g2o:3"):
                certislam.solve(path)
            with self.assertRaisesRegex(certislam.InputError, "missing.g2o"):
                certislam.read_g2o(Path(tmp) / "missing.g2o")


class Trajectories(unittest.TestCase):
    @staticmethod
    def trajectory(n=50):
        return np.array([transform(rot_z(0.1 * k), [k, np.sin(k), 0.2 * k]) for k in range(n)])

    def test_rigidly_moved_copy_has_zero_ate_after_alignment(self):
        gt = self.trajectory()
        T = transform(rot_z(0.7), [3.0, -2.0, 1.0])
        est = np.array([T @ P for P in gt])
        aligned = certislam.eval(gt, est)
        self.assertEqual(aligned["pairs"], len(gt))
        self.assertLess(aligned["ate_rmse"], 1e-9)
        self.assertLess(aligned["rpe_rmse"], 1e-9)
        np.testing.assert_allclose(aligned["T_gt_est"], np.linalg.inv(T), atol=1e-9)
        raw = certislam.eval(gt, est, align=False)
        self.assertGreater(raw["ate_rmse"], 1.0)

    def test_known_offset_gives_its_ate(self):
        # Every second pose 0.1 m off along z, the others exact: RMSE 0.1 / sqrt(2) unaligned.
        gt = self.trajectory(40)
        est = gt.copy()
        est[::2, 2, 3] += 0.1
        errors = certislam.eval(gt, est, align=False)
        self.assertAlmostEqual(errors["ate_rmse"], 0.1 / np.sqrt(2.0), places=12)

    def test_tum_round_trip_and_stamp_pairing(self):
        gt = self.trajectory(20)
        stamps = 100.0 + 0.1 * np.arange(len(gt))
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / "gt.tum"
            certislam.write_trajectory(path, gt, stamps)
            read_stamps, read_poses = certislam.read_trajectory(path)
        np.testing.assert_allclose(read_stamps, stamps, rtol=1e-15)
        np.testing.assert_allclose(read_poses, gt, atol=1e-12)
        # The estimate misses its first 5 poses: pairing by stamp still matches 15.
        errors = certislam.eval(gt, gt[5:], gt_stamps=stamps, est_stamps=stamps[5:])
        self.assertEqual(errors["pairs"], 15)
        self.assertLess(errors["ate_rmse"], 1e-9)


if __name__ == "__main__":
    unittest.main()
