#!/usr/bin/env python3
"""Identification from measured lines, in straightforward numpy.

The same computation as processing::identifyFromLines (direct method): each line's reading
row (d reading / d error at zero error) from the full homogeneous-transform model, here by
central differences vectorised over the nodes; per axis the unknowns (the errors the lines
name, then those the layout separates within the condition limit); per node the weighted
least squares of the readings relative to the first node; squareness from the slopes of the
straightness lines with the workpiece frame's orientation as a gauge; the least-squares line
removed from every straightness error.

Usage: model_identify_numpy.py INPUT.json [REPEATS]
INPUT: {"machine": ..., "lines": [{"measures", "coordinate", "q", "point_mm", "component",
"position_mm", "mean", "s"}], "max_condition": 1000}
Prints one JSON object: seconds (best of the repeats) and the identified node values.
"""
import json
import sys
import time

import numpy as np

from model_map_numpy import COMPONENT, rotation

H = 1.0  # finite-difference step: 1 um or 1 urad


class Machine:
    def __init__(self, m):
        self.m = m
        self.joints = m["joints"]
        self.coords = []
        for j in self.joints:
            if j.get("type", "fixed") != "fixed" and j["coordinate"] not in self.coords:
                self.coords.append(j["coordinate"])
        self.terms = []  # (name, joint, motion, component)
        for k, j in enumerate(self.joints):
            for kind, motion in (("motion_errors", True), ("static_errors", False)):
                for name, comp in j.get(kind, {}).items():
                    self.terms.append((name, k, motion, COMPONENT[comp]))
        bodies = [j["body"] for j in self.joints]

        def branch(body):
            chain = []
            while body != m.get("bed", "bed"):
                k = bodies.index(body)
                chain.insert(0, k)
                body = self.joints[k]["parent"]
            return chain

        self.tool, self.work = branch(m["tool"]), branch(m["workpiece"])
        self.tool_point = np.asarray(m.get("tool_point_mm", [0, 0, 0]), float)

    def coordinate_of_joint(self, k):
        j = self.joints[k]
        return -1 if j.get("type", "fixed") == "fixed" else self.coords.index(j["coordinate"])

    def error_matrices(self, v):
        """(n, 6) error vectors (um, urad) -> (n, 4, 4) transforms Rz Ry Rx with translation."""
        n = v.shape[0]
        rx, ry, rz = (v[:, 3 + k] * 1e-6 for k in range(3))
        zero, one = np.zeros(n), np.ones(n)

        def batch(rows):
            return np.stack([np.stack(r, axis=-1) for r in rows], axis=-2)

        cx, sx, cy, sy, cz, sz = np.cos(rx), np.sin(rx), np.cos(ry), np.sin(ry), np.cos(rz), np.sin(rz)
        r_x = batch([[one, zero, zero], [zero, cx, -sx], [zero, sx, cx]])
        r_y = batch([[cy, zero, sy], [zero, one, zero], [-sy, zero, cy]])
        r_z = batch([[cz, -sz, zero], [sz, cz, zero], [zero, zero, one]])
        m = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
        m[:, :3, :3] = r_z @ r_y @ r_x
        m[:, :3, 3] = v[:, :3] * 1e-3
        return m

    def chain(self, branch, q, errors):
        """Product of the joint matrices of a branch at q (n, coords) with errors (n, terms)."""
        n = q.shape[0]
        total = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
        for k in branch:
            j = self.joints[k]
            se, me = np.zeros((n, 6)), np.zeros((n, 6))
            for t, (_, joint, motion, comp) in enumerate(self.terms):
                if joint == k:
                    (me if motion else se)[:, comp] += errors[:, t]
            tp = np.eye(4)
            tp[:3, 3] = j.get("offset_mm", [0, 0, 0])
            ts = np.broadcast_to(np.eye(4), (n, 4, 4)).copy()
            c = self.coordinate_of_joint(k)
            if j.get("type", "fixed") == "prismatic":
                ts[:, :3, 3] = np.outer(q[:, c], np.asarray(j["axis"], float))
            elif j.get("type") == "revolute":
                for i in range(n):
                    ts[i, :3, :3] = rotation(j["axis"], np.radians(q[i, c]))
            total = total @ tp @ self.error_matrices(se) @ ts @ self.error_matrices(me)
        return total

    def pose(self, q, errors):
        return np.linalg.inv(self.chain(self.work, q, errors)) @ self.chain(self.tool, q, errors)

    def reading(self, q, errors, point, component):
        pose = self.pose(q, errors)
        if component < 3:
            return (pose[:, :3, :3] @ point + pose[:, :3, 3])[:, component] * 1000.0
        ideal = self.pose(q, np.zeros_like(errors))
        d = pose[:, :3, :3] @ np.transpose(ideal[:, :3, :3], (0, 2, 1))
        skew = 0.5 * np.stack([d[:, 2, 1] - d[:, 1, 2], d[:, 0, 2] - d[:, 2, 0], d[:, 1, 0] - d[:, 0, 1]], axis=1)
        return skew[:, component - 3] * 1e6

    def rows(self, q, point, component):
        """(n, terms) reading rows at the n configurations q, by central differences."""
        n, terms = q.shape[0], len(self.terms)
        out = np.zeros((n, terms))
        for t in range(terms):
            e = np.zeros((n, terms))
            e[:, t] = H
            out[:, t] = (self.reading(q, e, point, component) - self.reading(q, -e, point, component)) / (2 * H)
        return out


def slope(x, y):
    return np.polyfit(x, y, 1)[0]


def identify(machine, lines, max_condition):
    terms = machine.terms
    index = {t[0]: i for i, t in enumerate(terms)}
    for line in lines:
        x = np.asarray(line["position_mm"], float)
        q = np.tile(np.asarray(line["q"], float), (len(x), 1))
        q[:, line["coordinate"]] = x
        line["x"] = x
        line["qs"] = q
        line["rows"] = machine.rows(q, np.asarray(line["point_mm"], float), line["component"])
        line["y"] = np.asarray(line["mean"], float)
        line["w"] = 1.0 / np.asarray(line["s"], float) ** 2
    curves = {}
    for coordinate in sorted({line["coordinate"] for line in lines}):
        members = [line for line in lines if line["coordinate"] == coordinate]
        own = [t for t, (_, joint, motion, _) in enumerate(terms) if motion and machine.coordinate_of_joint(joint) == coordinate]
        unknowns = []
        for line in members:
            if index[line["measures"]] not in unknowns:
                unknowns.append(index[line["measures"]])
        a0 = np.array([line["rows"][0] for line in members])
        for rotations in (True, False):
            for t in own:
                if (terms[t][3] >= 3) != rotations or t in unknowns:
                    continue
                trial = a0[:, unknowns + [t]]
                if np.linalg.norm(trial[:, -1]) < 1e-12 or trial.shape[0] < trial.shape[1]:
                    continue
                sv = np.linalg.svd(trial, compute_uv=False)
                if sv[-1] > 1e-9 * sv[0] and sv[0] / sv[-1] <= max_condition:
                    unknowns.append(t)
        x = members[0]["x"]
        values = np.zeros((len(x), len(unknowns)))
        for n in range(len(x)):
            a = np.array([line["rows"][n][unknowns] for line in members])
            y = np.array([line["y"][n] - line["y"][0] for line in members])
            w = np.array([line["w"][n] for line in members])
            values[n] = np.linalg.solve(a.T @ (w[:, None] * a), a.T @ (w * y))
        for k, t in enumerate(unknowns):
            curves[terms[t][0]] = (x, values[:, k])

    def straightness(t):
        name, joint, motion, comp = terms[t]
        j = machine.joints[joint]
        if not motion or j.get("type", "fixed") != "prismatic" or comp >= 3:
            return False
        return comp != int(np.argmax(np.abs(j["axis"])))

    statics = [t for t, term in enumerate(terms) if not term[2]]
    sl = [line for line in lines if straightness(index[line["measures"]]) and line["component"] < 3]
    if sl and statics:
        g_static, g_gauge, observed = [], [], []
        for line in sl:
            d_row = (line["rows"][-1] - line["rows"][0]) / (line["x"][-1] - line["x"][0])
            own_term = index[line["measures"]]
            z = line["y"].copy()
            for name, (cx, cy) in curves.items():
                t = index[name]
                if t == own_term:
                    continue
                c = machine.coordinate_of_joint(terms[t][1])
                at = line["x"] if c == line["coordinate"] else np.full(len(line["x"]), line["q"][c])
                z -= line["rows"][:, t] * np.interp(at, cx, cy)
            observed.append(slope(line["x"], z))
            g_static.append(d_row[statics])
            point = np.asarray(line["point_mm"], float)
            ends = machine.pose(line["qs"][[0, -1]], np.zeros((2, len(terms))))
            p = ends[:, :3, :3] @ point + ends[:, :3, 3]
            u = (p[1] - p[0]) / (line["x"][-1] - line["x"][0])
            g_gauge.append([-np.cross(np.eye(3)[m], u)[line["component"]] * 1e-3 for m in range(3)])
        g_static, g_gauge, observed = np.array(g_static), np.array(g_gauge), np.array(observed)
        columns, chosen = [], []

        def full_rank(col):
            m = np.column_stack(columns + [col])
            if m.shape[0] < m.shape[1]:
                return False
            sv = np.linalg.svd(m, compute_uv=False)
            return sv[-1] > 1e-9 * sv[0]

        for m in range(3):
            if np.linalg.norm(g_gauge[:, m]) > 1e-12 and full_rank(g_gauge[:, m]):
                columns.append(g_gauge[:, m])
        gauge = len(columns)
        for k, t in enumerate(statics):
            if np.linalg.norm(g_static[:, k]) > 1e-12 and full_rank(g_static[:, k]):
                columns.append(g_static[:, k])
                chosen.append(t)
        if chosen:
            solution = np.linalg.lstsq(np.column_stack(columns), observed, rcond=None)[0]
            for k, t in enumerate(chosen):
                curves[terms[t][0]] = (np.array([]), np.array([solution[gauge + k]]))
    for name, (cx, cy) in list(curves.items()):
        if len(cx) >= 2 and straightness(index[name]):
            b, a = np.polyfit(cx, cy, 1)
            curves[name] = (cx, cy - (a + b * cx))
    return curves


def main():
    data = json.load(open(sys.argv[1]))
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 3
    machine = Machine(data["machine"])
    best, curves = None, None
    for _ in range(repeats):
        lines = [dict(line) for line in data["lines"]]
        start = time.perf_counter()
        curves = identify(machine, lines, data.get("max_condition", 1000.0))
        elapsed = time.perf_counter() - start
        best = elapsed if best is None else min(best, elapsed)
    print(json.dumps({"seconds": best, "curves": {name: cy.tolist() for name, (cx, cy) in curves.items()}}))


if __name__ == "__main__":
    main()
