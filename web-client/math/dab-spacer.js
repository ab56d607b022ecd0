// Turns the samples of a pointer drag into evenly spaced brush dabs.
// Conventions: world points in vu; screen points in CSS pixels (y down); pressure in (0, 1].
// Spacing is measured along the surface path, the polyline through the samples' surface hits,
// so dabs stay evenly spaced on the model whatever the zoom. The first hit of a drag is a dab.
// A sample that missed the surface breaks the path; so does a jump longer than `maxGap` (the
// cursor slid over a silhouette onto a far part), after which the next hit starts afresh
// instead of filling the gap with dabs in the air.

import { distance, lerp } from "./vec3.js";

export class DabSpacer {
  // spacing: vu between dabs (> 0); maxGap: vu, a longer step starts a new path.
  constructor(spacing, maxGap = 8 * spacing) {
    if (!(spacing > 0)) throw new RangeError(`dab spacing must be positive, got ${spacing}`);
    this.spacing = spacing;
    this.maxGap = maxGap;
    this.last = null; // {point, screen, pressure} of the previous sample that hit
    this.travelled = 0; // path length since the last dab, vu
  }

  // One sample of the drag: `point` is the surface hit under `screen`, or null for a miss.
  // Returns the dabs it completes, in order: [{point, screen, pressure}].
  add(point, screen, pressure) {
    if (!point) {
      this.last = null;
      return [];
    }
    const sample = { point, screen, pressure };
    const prev = this.last;
    this.last = sample;
    if (!prev) {
      this.travelled = 0;
      return [sample];
    }
    const step = distance(prev.point, point);
    if (step > this.maxGap) {
      this.travelled = 0;
      return [sample];
    }
    const dabs = [];
    let along = this.spacing - this.travelled; // distance into this step of the next dab
    while (along <= step) {
      const f = along / step;
      dabs.push({
        point: lerp(prev.point, point, f),
        screen: [prev.screen[0] + (screen[0] - prev.screen[0]) * f, prev.screen[1] + (screen[1] - prev.screen[1]) * f],
        pressure: prev.pressure + (pressure - prev.pressure) * f,
      });
      along += this.spacing;
    }
    this.travelled = step - (along - this.spacing);
    return dabs;
  }
}
