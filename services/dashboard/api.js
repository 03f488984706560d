// tcfarm dashboard: talking to the coordinator's HTTP API (proto/openapi.yaml).
//
// A farm with API tokens answers 401: the page then asks for a token and sends it as
// "Authorization: Bearer" on every request, images and the event stream included (fetched,
// never put in a URL the server sees). The token is kept in localStorage when the user asks
// to be remembered on this browser, else in this tab's sessionStorage.
"use strict";

const API = "api/v1";
const TOKEN_KEY = "tcfarm-api-token";

// An answer of the farm in its one error shape, {"error": {status, code, message, pointer}},
// or a transport failure (status 0). `message` is for people and is what the page shows.
class ApiError extends Error {
  constructor(status, code, message, pointer) {
    super(message);
    this.status = status;
    this.code = code;
    this.pointer = pointer;
  }

  // In plain words: the farm's message, where in the request it was, and its code.
  get plain() {
    const where = this.pointer ? ` (at ${this.pointer})` : "";
    return `${this.message}${where}` + (this.code ? ` [${this.code}]` : "");
  }
}

function storedToken() {
  return sessionStorage.getItem(TOKEN_KEY) || localStorage.getItem(TOKEN_KEY);
}

function storeToken(token, remember) {
  forgetToken();
  (remember ? localStorage : sessionStorage).setItem(TOKEN_KEY, token.trim());
}

function forgetToken() {
  sessionStorage.removeItem(TOKEN_KEY);
  localStorage.removeItem(TOKEN_KEY);
}

function authHeaders(extra = {}) {
  const token = storedToken();
  return token ? Object.assign({ Authorization: `Bearer ${token}` }, extra) : extra;
}

// Called with a message when the farm wants a (different) token; the page sets it.
let onUnauthorized = () => {};

async function errorOf(response, what) {
  let body = null;
  try { body = await response.json(); } catch (e) { /* not JSON: a proxy's page, say */ }
  const error = body && body.error;
  if (error && error.message) return new ApiError(response.status, error.code, error.message, error.pointer);
  return new ApiError(response.status, "", `${what}: HTTP ${response.status} ${response.statusText}`.trim());
}

// fetch with the token; a non-2xx answer throws ApiError with the farm's own words.
async function apiFetch(path, options = {}) {
  const init = Object.assign({ cache: "no-store" }, options);
  init.headers = authHeaders(options.headers || {});
  let response;
  try {
    response = await fetch(path, init);
  } catch (e) {
    throw new ApiError(0, "unreachable", `cannot reach the farm (${e.message || e})`);
  }
  if (response.status === 401) {
    onUnauthorized(storedToken() ? "The farm does not know this token." : "This farm needs an API token.");
  }
  if (!response.ok) throw await errorOf(response, `${init.method || "GET"} ${path}`);
  return response;
}

async function getJson(path) {
  return (await apiFetch(path)).json();
}

// A JSON request (POST, PATCH, DELETE); returns the answer's JSON.
async function sendJson(method, path, body) {
  const options = { method };
  if (body !== undefined) {
    options.body = JSON.stringify(body);
    options.headers = { "Content-Type": "application/json" };
  }
  return (await apiFetch(path, options)).json();
}

// --- the farm's live events: GET /api/v1/events, Server-Sent Events --------------------
//
// Read with fetch rather than EventSource, which cannot send the Authorization header.
// A dropped stream is opened again after a back-off, with Last-Event-ID, so no event is
// lost; a farm without the stream (404, 405) is asked again only now and then.

const STREAM_RETRY_MS = [500, 1000, 2000, 5000, 10000];
const STREAM_ABSENT_RETRY_MS = 30000;
// The farm says something (": keepalive") at least every 15 s; a stream silent for longer
// than this is a connection that died without a word, and is opened again.
const STREAM_SILENCE_MS = 40000;

// Parses "field: value" lines; a blank line ends an event (WHATWG's text/event-stream).
class EventStreamParser {
  constructor(onEvent) {
    this.onEvent = onEvent;
    this.buffer = "";
    this.fields = {};
    this.data = [];
  }

  push(text) {
    this.buffer += text;
    let end;
    while ((end = this.buffer.search(/\r\n|\r|\n/)) >= 0) {
      const line = this.buffer.slice(0, end);
      this.buffer = this.buffer.slice(end + (this.buffer.startsWith("\r\n", end) ? 2 : 1));
      this.line(line);
    }
  }

  line(line) {
    if (line === "") {
      if (this.data.length) {
        let event;
        try { event = JSON.parse(this.data.join("\n")); } catch (e) { event = { message: this.data.join("\n") }; }
        if (event && typeof event === "object") {
          if (event.seq === undefined && this.fields.id !== undefined) event.seq = Number(this.fields.id);
          if (event.type === undefined && this.fields.event !== undefined) event.type = this.fields.event;
          this.onEvent(event);
        }
      }
      this.fields = {};
      this.data = [];
      return;
    }
    if (line.startsWith(":")) return;  // a comment: the farm's keep-alive
    const colon = line.indexOf(":");
    const name = colon < 0 ? line : line.slice(0, colon);
    let value = colon < 0 ? "" : line.slice(colon + 1);
    if (value.startsWith(" ")) value = value.slice(1);
    if (name === "data") this.data.push(value);
    else if (name === "id" || name === "event") this.fields[name] = value;
  }
}

// Cuts the back-off short: the next try is now (a token was just given, say).
// Asked while the stream is being opened (a sign-in during a fetch): the next wait is skipped.
let retryAsked = false;
let retryEventsNow = () => {
  retryAsked = true;
};

// Follows the stream for as long as the page lives. handlers: onEvent(event),
// onState("live" | "connecting" | "absent" | "error", detail).
async function followEvents(handlers) {
  let lastSeq = null;
  let failures = 0;
  for (;;) {
    let wait = STREAM_RETRY_MS[Math.min(failures, STREAM_RETRY_MS.length - 1)];
    const abort = new AbortController();
    let silence = null;
    const listen = () => {
      clearTimeout(silence);
      silence = setTimeout(() => abort.abort(), STREAM_SILENCE_MS);
    };
    try {
      const headers = { Accept: "text/event-stream" };
      if (lastSeq !== null) headers["Last-Event-ID"] = String(lastSeq);
      listen();
      const response = await apiFetch(`${API}/events`, { headers, signal: abort.signal });
      handlers.onState("live");
      failures = 0;
      const parser = new EventStreamParser((event) => {
        if (typeof event.seq === "number") lastSeq = event.seq;
        handlers.onEvent(event);
      });
      const reader = response.body.getReader();
      const decoder = new TextDecoder();
      for (;;) {
        listen();
        const { value, done } = await reader.read();
        if (done) break;
        parser.push(decoder.decode(value, { stream: true }));
      }
      handlers.onState("connecting", "the event stream ended; opening it again");
    } catch (error) {
      failures += 1;
      if (error.status === 404 || error.status === 405) {
        wait = STREAM_ABSENT_RETRY_MS;
        handlers.onState("absent", "this farm has no event stream");
      } else {
        handlers.onState("error", error.plain || String(error.message || error));
      }
    } finally {
      clearTimeout(silence);
    }
    await new Promise((resolve) => {
      if (retryAsked) {
        resolve();
        return;
      }
      const timer = setTimeout(resolve, wait);
      retryEventsNow = () => {
        clearTimeout(timer);
        resolve();
      };
    });
    retryAsked = false;
    retryEventsNow = () => {
      retryAsked = true;
    };
  }
}
