// A stroke stabiliser ("lazy mouse"): the brush hangs on a string of `slack` CSS pixels behind
// the pointer and moves only when the pointer pulls the string tight, so a shaky hand draws a
// calm line and corners are rounded by at most the slack. With a slack of 0 the brush is the
// pointer.
// Conventions: positions in CSS pixels of the canvas; a pressure travels with the brush.

export class LazyMouse {
  constructor(slack) {
    this.slack = Math.max(0, slack);
    this.at = null; // [x, y] of the brush, once the stroke has begun
  }

  // The brush's new position after the pointer moved to (x, y), or null while the string is slack.
  follow(x, y) {
    if (!this.at || this.slack === 0) {
      this.at = [x, y];
      return [x, y];
    }
    const dx = x - this.at[0], dy = y - this.at[1];
    const d = Math.hypot(dx, dy);
    if (d <= this.slack) return null;
    const k = (d - this.slack) / d;
    this.at = [this.at[0] + dx * k, this.at[1] + dy * k];
    return [...this.at];
  }
}
