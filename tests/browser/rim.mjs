// Measures of a close-up picture's rims (the tests' screenshots, decoded by png.mjs): how
// scalloped its sharp edges are, and whether the backdrop shows through the model.
// Conventions: img = {width, height, rgba}; box = [x0, y0, x1, y1] in fractions of the picture;
// luminance 0-255 (Rec. 709 weights of the sRGB values).

// Pixels of the box taken as rim: the EDGE_SHARE of them where the luminance changes fastest.
const EDGE_SHARE = 0.03;
// Half the side of the window, px, over which an edge's direction is compared: about a
// scallop's length in the close-up (a disc is ~20 px across there).
const WINDOW = 8;

// Scalloping of the rims: at the pixels where the luminance changes fastest (the rims' edges,
// the top EDGE_SHARE of the box by gradient magnitude), 1 - the coherence of the gradient's
// direction within a (2 WINDOW + 1)^2 window (the structure tensor's (l1 - l2) / (l1 + l2)),
// averaged. A straight edge, however soft, scores 0; a row of round outlines, whose gradient
// swings from one bead to the next, scores towards 1.
export function rimRoughness(img, box) {
  const { x0, y0, w, h } = pixelsOf(img, box);
  const lum = new Float32Array(w * h);
  for (let y = 0; y < h; ++y)
    for (let x = 0; x < w; ++x) {
      const o = ((y0 + y) * img.width + x0 + x) * 4;
      lum[y * w + x] = 0.2126 * img.rgba[o] + 0.7152 * img.rgba[o + 1] + 0.0722 * img.rgba[o + 2];
    }
  // Sobel gradients (0 on the box's border) and the tensor's products.
  const jxx = new Float64Array(w * h), jxy = new Float64Array(w * h), jyy = new Float64Array(w * h);
  const magnitude = new Float32Array(w * h);
  const at = (x, y) => lum[y * w + x];
  for (let y = 1; y < h - 1; ++y)
    for (let x = 1; x < w - 1; ++x) {
      const gx = at(x + 1, y - 1) + 2 * at(x + 1, y) + at(x + 1, y + 1) - at(x - 1, y - 1) - 2 * at(x - 1, y) - at(x - 1, y + 1);
      const gy = at(x - 1, y + 1) + 2 * at(x, y + 1) + at(x + 1, y + 1) - at(x - 1, y - 1) - 2 * at(x, y - 1) - at(x + 1, y - 1);
      const i = y * w + x;
      jxx[i] = gx * gx;
      jxy[i] = gx * gy;
      jyy[i] = gy * gy;
      magnitude[i] = Math.hypot(gx, gy);
    }
  const [sxx, sxy, syy] = [jxx, jxy, jyy].map((j) => boxSum(j, w, h, WINDOW));
  const threshold = quantile(magnitude, 1 - EDGE_SHARE);
  let sum = 0, n = 0;
  for (let y = WINDOW; y < h - WINDOW; ++y)
    for (let x = WINDOW; x < w - WINDOW; ++x) {
      const i = y * w + x;
      if (magnitude[i] < threshold || magnitude[i] === 0) continue;
      const trace = sxx[i] + syy[i];
      const coherence = Math.hypot(sxx[i] - syy[i], 2 * sxy[i]) / trace;
      sum += 1 - coherence;
      ++n;
    }
  return n ? sum / n : 0;
}

// Pixels of the box where the backdrop shows (its blue-grey, not the clay's warm colour: blue
// at least red): holes, where the model fills the box.
export function backdropPixels(img, box) {
  const { x0, y0, w, h } = pixelsOf(img, box);
  let count = 0;
  for (let y = y0; y < y0 + h; ++y)
    for (let x = x0; x < x0 + w; ++x) {
      const o = (y * img.width + x) * 4;
      if (img.rgba[o + 2] >= img.rgba[o]) ++count;
    }
  return count;
}

function pixelsOf(img, box) {
  const [x0, y0, x1, y1] = [box[0] * img.width, box[1] * img.height, box[2] * img.width, box[3] * img.height].map(Math.round);
  return { x0, y0, w: x1 - x0, h: y1 - y0 };
}

// Sums of `a` (w x h) over the (2 r + 1)^2 window around each pixel (clipped at the borders),
// from a summed-area table.
function boxSum(a, w, h, r) {
  const s = new Float64Array((w + 1) * (h + 1));
  for (let y = 0; y < h; ++y)
    for (let x = 0; x < w; ++x) s[(y + 1) * (w + 1) + x + 1] = a[y * w + x] + s[y * (w + 1) + x + 1] + s[(y + 1) * (w + 1) + x] - s[y * (w + 1) + x];
  const out = new Float64Array(w * h);
  for (let y = 0; y < h; ++y)
    for (let x = 0; x < w; ++x) {
      const xa = Math.max(0, x - r), xb = Math.min(w, x + r + 1), ya = Math.max(0, y - r), yb = Math.min(h, y + r + 1);
      out[y * w + x] = s[yb * (w + 1) + xb] - s[ya * (w + 1) + xb] - s[yb * (w + 1) + xa] + s[ya * (w + 1) + xa];
    }
  return out;
}

function quantile(values, q) {
  const sorted = Float32Array.from(values).sort();
  return sorted[Math.min(sorted.length - 1, Math.floor(q * sorted.length))];
}

// The beads along a round rim seen face on (the pig's snout in the front orthographic view):
// the luminance sampled (bilinearly) on circles about `centre` (px) with radii from 0.8 to
// 1.15 `radius` in steps of 0.05, at RAYS angles each, minus its mean over the angles within
// SMOOTH_RAYS either side, as an RMS over all samples. The rim's slow change of shading around
// the circle is taken out by the mean; what remains is the ripple of discs a voxel or two
// across.
const RAYS = 720;
const SMOOTH_RAYS = 15; // +-7.5 degrees, about four voxels along a rim of radius 7 vu
export function rimRipple(img, centre, radius) {
  let sum = 0, n = 0;
  for (let f = 0.8; f < 1.15 + 1e-9; f += 0.05) {
    const ring = new Float64Array(RAYS);
    for (let k = 0; k < RAYS; ++k) {
      const a = (2 * Math.PI * k) / RAYS;
      ring[k] = luminance(sample(img, centre[0] + f * radius * Math.cos(a), centre[1] + f * radius * Math.sin(a)));
    }
    for (let k = 0; k < RAYS; ++k) {
      let mean = 0;
      for (let j = -SMOOTH_RAYS; j <= SMOOTH_RAYS; ++j) mean += ring[(k + j + RAYS) % RAYS];
      sum += (ring[k] - mean / (2 * SMOOTH_RAYS + 1)) ** 2;
      ++n;
    }
  }
  return Math.sqrt(sum / n);
}

function luminance(c) {
  return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}

// The picture's colour at (x, y), px from its top left corner, interpolated bilinearly
// (pixel centres at half-integers).
function sample(img, x, y) {
  const fx = x - 0.5, fy = y - 0.5;
  const x0 = Math.floor(fx), y0 = Math.floor(fy), tx = fx - x0, ty = fy - y0;
  const out = [0, 0, 0];
  for (const [px, py, w] of [[x0, y0, (1 - tx) * (1 - ty)], [x0 + 1, y0, tx * (1 - ty)], [x0, y0 + 1, (1 - tx) * ty], [x0 + 1, y0 + 1, tx * ty]]) {
    const o = (Math.min(img.height - 1, Math.max(0, py)) * img.width + Math.min(img.width - 1, Math.max(0, px))) * 4;
    for (let c = 0; c < 3; ++c) out[c] += w * img.rgba[o + c];
  }
  return out;
}
