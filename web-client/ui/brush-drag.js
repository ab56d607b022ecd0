// F+drag changes the brush: sideways scales the radius (by e every RADIUS_PX_PER_E pixels), up
// and down moves the strength (or a CSG tool's blend) by STRENGTH_PER_PX a pixel. The new
// values follow from the whole drag since the press, not from each pointer event, so a slow
// drag of many 1-pixel steps ends where one fast 100-pixel step does (the controls round what
// they show, and rounding every step on its own would lose the small ones).

export const RADIUS_PX_PER_E = 100;
export const STRENGTH_PER_PX = 0.005;

export class BrushDrag {
  // radius: vu at the press; second: strength (or blend) at the press.
  constructor(radius, second) {
    this.radius = radius;
    this.second = second;
  }

  // The brush for a drag of (dx, dy) CSS pixels from the press point (y down).
  at(dx, dy) {
    return { radius: this.radius * Math.exp(dx / RADIUS_PX_PER_E), second: this.second - dy * STRENGTH_PER_PX };
  }
}
