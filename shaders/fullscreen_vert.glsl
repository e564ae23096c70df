// SPDX-License-Identifier: Apache-2.0
// Vertex stage of every Crisp filter pass: one triangle covering the target
// (pos in normalised device coordinates, e.g. (-1,-1), (3,-1), (-1,3)); the
// fragment stages address pixels by gl_FragCoord, so nothing is interpolated.
void main() { gl_Position = vec4(pos, 0.0, 1.0); }
