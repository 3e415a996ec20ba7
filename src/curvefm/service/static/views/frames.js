// Frames: one animation frame draws every viewport that changed. A viewport whose pixels someone awaits is
// drawn at once, and the others hold off until those pixels exist.

export class FrameLoop {
  constructor() {
    this.dirty = new Set(); // viewports to draw at the next frame
    this.requested = false; // an animation frame is requested
    this.awaited = 0; // draws someone waits for: other viewports hold off until those pixels exist
  }

  request(viewport) {
    this.dirty.add(viewport);
    this.schedule();
  }

  schedule() {
    if (this.requested || this.awaited > 0 || this.dirty.size === 0) return;
    this.requested = true;
    requestAnimationFrame(() => this.drawFrame());
  }

  drawFrame() {
    this.requested = false;
    if (this.awaited > 0) return; // drawn() schedules the frame again once its pixels exist
    for (const viewport of this.dirty) viewport.draw();
    this.dirty.clear();
  }

  /** Draw ``viewport`` now, not at the next animation frame (up to 16 ms away: the browser shows a canvas drawn
   * between frames at the next one anyway); resolves with performance.now() once its pixels exist (not merely
   * once the commands were issued: the renderer may run in another process, or on the CPU). Until then the
   * other viewports wait, so that a software renderer works on the awaited pixels first. */
  async drawn(viewport) {
    this.awaited += 1;
    this.dirty.delete(viewport);
    viewport.draw();
    try {
      return await viewport.pixelsDone();
    } finally {
      this.awaited -= 1;
      this.schedule();
    }
  }
}
