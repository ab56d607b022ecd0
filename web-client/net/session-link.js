// Session ids and share links.
// Conventions: a link carries the session id and a token in the URL fragment
// (#session=ID&token=TOKEN), which browsers never send in an HTTP request; the WebSocket URL
// carries only the id (/ws?session=ID), on which a load balancer routes (PROTOCOL.md,
// "Transport"). Ids are [A-Za-z0-9_-]{1,64} and tokens [A-Za-z0-9_-]{1,128} (PROTOCOL.md,
// session.create); anything else in a fragment is not a link of ours. A link may also say where
// the model's front is (&front=+x, one of FRONT_AXES of math/orbit-camera.js), so that the
// Front view of whoever opens it looks at the pig's face; an unknown value is ignored.

const ID_PATTERN = /^[A-Za-z0-9_-]{1,64}$/;
const TOKEN_PATTERN = /^[A-Za-z0-9_-]{1,128}$/;
const FRONT_PATTERN = /^[+-][xz]$/;
const BASE64URL = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789-_";

// A new session id to propose to session.create: 22 base64url characters, 132 random bits.
export function newSessionId(random = (bytes) => crypto.getRandomValues(bytes)) {
  const bytes = random(new Uint8Array(22));
  let id = "";
  for (const b of bytes) id += BASE64URL[b & 63];
  return id;
}

// {session, token, front} from a fragment ("#session=..&token=..[&front=..]") or a whole link
// (front null when absent); null when it is not a session link.
export function parseSessionLink(text) {
  if (typeof text !== "string") return null;
  const hash = text.includes("#") ? text.slice(text.indexOf("#") + 1) : text;
  const params = new URLSearchParams(hash);
  const session = params.get("session");
  const token = params.get("token");
  if (!session || !token || !ID_PATTERN.test(session) || !TOKEN_PATTERN.test(token)) return null;
  const front = params.get("front");
  return { session, token, front: front && FRONT_PATTERN.test(front) ? front : null };
}

// The link that opens `session` with `token` on the page at `pageUrl` (its fragment replaced),
// with the model's `front` when one is given.
export function sessionLink(pageUrl, session, token, front = null) {
  const base = String(pageUrl).split("#")[0];
  const link = `${base}#session=${encodeURIComponent(session)}&token=${encodeURIComponent(token)}`;
  return front && FRONT_PATTERN.test(front) ? `${link}&front=${encodeURIComponent(front)}` : link;
}

// ws://HOST/ws?session=ID for a page at `pageUrl` (wss for https).
export function socketUrl(pageUrl, session) {
  const url = new URL("/ws", pageUrl);
  url.protocol = url.protocol === "https:" ? "wss:" : "ws:";
  url.search = `?session=${encodeURIComponent(session)}`;
  url.hash = "";
  return url.href;
}
