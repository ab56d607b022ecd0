// The sessions this browser opened recently, so that a closed tab or a "New…" does not lose a
// session: the start screen lists them with their links. Kept in the browser's localStorage
// (never sent anywhere), newest first, at most MAX_RECENT, one entry per session (the edit
// token wins over a view token for the same session).
// An entry: {session, token, readOnly, size: [nx, ny, nz], front (the model's front axis, or
// null), openedAt: ms since the epoch}.

export const MAX_RECENT = 12;
const KEY = "marzipan.recent-sessions";

export class RecentSessions {
  // storage: a Web Storage object (window.localStorage), or null where the browser refuses one.
  constructor(storage) {
    this.storage = storage;
  }

  list() {
    if (!this.storage) return [];
    try {
      const entries = JSON.parse(this.storage.getItem(KEY) || "[]");
      return Array.isArray(entries) ? entries.filter(valid) : [];
    } catch {
      return [];
    }
  }

  remember({ session, token, readOnly, size, front = null }, now = Date.now()) {
    const old = this.list();
    const same = old.find((e) => e.session === session);
    const keep = same && same.token !== token && !same.readOnly && readOnly ? same : { session, token, readOnly: Boolean(readOnly), size, front: front || (same && same.front) || null };
    const entries = [{ ...keep, openedAt: now }, ...old.filter((e) => e.session !== session)].slice(0, MAX_RECENT);
    this.#save(entries);
  }

  // The entry of `session`, or null.
  find(session) {
    return this.list().find((e) => e.session === session) || null;
  }

  forget(session) {
    this.#save(this.list().filter((e) => e.session !== session));
  }

  #save(entries) {
    if (!this.storage) return;
    try {
      this.storage.setItem(KEY, JSON.stringify(entries));
    } catch {
      // A full or disabled storage only costs the list of recent sessions.
    }
  }
}

function valid(e) {
  return e && typeof e.session === "string" && typeof e.token === "string" && Array.isArray(e.size) && typeof e.openedAt === "number";
}
