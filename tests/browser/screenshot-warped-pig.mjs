// Warps the pig through the web client with the mouse (issue 29's tools) and saves the canvas
// as web-client/images/warped-pig.png (a picture of web-client/README.md): a grab pulls its
// right ear up, a snake hook draws out its tail, a twist turns its snout.
// Usage: MARZIPAN=build/server/marzipan node tests/browser/screenshot-warped-pig.mjs [OUT.png]
// Positions: fractions of the canvas in the client's default view (pig-shot.mjs); each stroke
// [tool, radius, path] is dragged through its points.

import { join } from "node:path";

import { repoRoot } from "./harness.mjs";
import { shootPig } from "./pig-shot.mjs";

const plan = [
  ["grab", 8, [[0.436, 0.27], [0.47, 0.15]]],
  ["snake_hook", 5, [[0.652, 0.293], [0.72, 0.27], [0.77, 0.2], [0.75, 0.13]]],
  ["twist", 12, [[0.242, 0.55], [0.3, 0.55]]],
];
await shootPig(process.argv[2] || join(repoRoot, "web-client/images/warped-pig.png"), async ({ stroke }) => {
  for (const [tool, radius, points] of plan) await stroke(tool, radius, points, { steps: 6 });
});
