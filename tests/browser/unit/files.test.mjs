// web-client/ui/files.js: the volume format of a picked file.
import { test } from "node:test";
import assert from "node:assert/strict";

import { volumeFormatOf } from "../../../web-client/ui/files.js";

test("a picked file is loaded as .vdb by its extension, anything else as .mzv", () => {
  assert.equal(volumeFormatOf("pig.vdb"), "vdb");
  assert.equal(volumeFormatOf("PIG.VDB"), "vdb");
  assert.equal(volumeFormatOf("marzipan-1a2b3c4d-r12.mzv"), "mzv");
  assert.equal(volumeFormatOf("vdb.mzv"), "mzv");
  assert.equal(volumeFormatOf("pig.vdb.txt"), "mzv");
});
