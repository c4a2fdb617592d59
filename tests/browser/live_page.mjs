// Drives Debian's headless chromium (through playwright-core) against rigd's live page while a
// simulated capture runs, and prints one JSON document of what the page showed:
//   node live_page.mjs URL TOKEN SCREENSHOT.png
// The C++ test (tests/unit/daemon/live_page_browser_test.cpp) starts the daemon and judges the
// result. Every wait is bounded; the whole run takes a few seconds.
import fs from "node:fs";
import os from "node:os";
import path from "node:path";
import { chromium } from "playwright-core";

const [url, token, screenshot] = process.argv.slice(2);
const executablePath = process.env.CHROMIUM || "/usr/bin/chromium";
const out = { ok: false };
const profile = fs.mkdtempSync(path.join(os.tmpdir(), "hardcopy-chromium-"));
let context;
try {
  context = await chromium.launchPersistentContext(profile, {
    executablePath,
    headless: true,
    timeout: 30000,
    viewport: { width: 1280, height: 1000 },
    args: ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
           "--disable-background-networking", "--disable-component-update", "--disable-sync"],
  });
  const page = context.pages()[0] || (await context.newPage());
  page.setDefaultTimeout(10000);

  // With the token: the page takes it from the URL and enables the controls.
  await page.goto(url + "?token=" + token, { waitUntil: "domcontentloaded" });
  await page.waitForSelector("#devices tbody tr");
  await page.waitForFunction(() => Number(document.body.dataset.updates) >= 3);
  await page.waitForFunction(() => document.body.dataset.mode === "control");
  const read = () => page.evaluate(() => ({
    updates: Number(document.body.dataset.updates),
    seq: Number(document.body.dataset.seq),
    state: document.getElementById("state").textContent,
    done: Number(document.getElementById("progress-text").dataset.done || 0),
    progress: document.getElementById("progress-text").textContent,
    timeLeft: document.getElementById("time-left").textContent,
    plotPoints: Number(document.getElementById("force-plot").dataset.points || 0),
    plotLastT: Number(document.getElementById("force-plot").dataset.lastT || 0),
    plotPath: document.getElementById("force-line").getAttribute("points"),
    arm: document.getElementById("arm-pose").textContent,
    motion: document.getElementById("arm-motion").textContent,
    safety: document.getElementById("safety-state").textContent,
    devices: [...document.querySelectorAll("#devices tbody tr")].map((tr) => ({
      name: tr.dataset.device, state: tr.cells[3].textContent, received: tr.cells[4].textContent })),
    addressBar: location.href,
  }));
  out.first = await read();
  const t0 = Date.now();
  await page.waitForTimeout(1500);
  out.second = await read();
  out.second_after_ms = Date.now() - t0;
  // Camera thumbnails arrive (a decoded image with pixels).
  await page.waitForFunction(() => [...document.querySelectorAll("#thumbs img")].some((i) => i.naturalWidth > 0));
  out.thumbnails = await page.evaluate(() => [...document.querySelectorAll("#thumbs img")].map(
      (i) => ({ camera: i.dataset.camera, width: i.naturalWidth, height: i.naturalHeight })));
  await page.screenshot({ path: screenshot, fullPage: true });

  // Without the token (a new tab: sessionStorage is per tab): read-only, and every control
  // request is refused by rigd.
  const guest = await context.newPage();
  await guest.goto(url, { waitUntil: "domcontentloaded" });
  await guest.waitForFunction(() => Number(document.body.dataset.updates) >= 1);
  out.guest = await guest.evaluate(async () => {
    const statuses = {};
    for (const c of ["pause", "resume", "stop", "estop", "reset", "start"])
      statuses[c] = (await fetch("/api/" + c, { method: "POST", body: c === "start" ? "protocol: automated" : undefined })).status;
    const wrong = (await fetch("/api/stop", { method: "POST", headers: { Authorization: "Bearer nope" } })).status;
    return { mode: document.getElementById("mode").textContent,
             estopDisabled: document.getElementById("estop").disabled, statuses, wrong };
  });
  out.after_guest = await read();

  // With the token: the page's own emergency stop.
  await page.click("#estop");
  await page.waitForFunction(() => /estop: ok/.test(document.getElementById("message").textContent));
  await page.waitForFunction(() => document.getElementById("safety-state").textContent === "estop" ||
                                    document.getElementById("state").textContent === "aborted");
  out.after_estop = await read();
  out.ok = true;
} catch (e) {
  out.error = String(e && e.stack ? e.stack : e);
} finally {
  if (context) await context.close().catch(() => {});
  fs.rmSync(profile, { recursive: true, force: true });
}
process.stdout.write(JSON.stringify(out) + "\n");
