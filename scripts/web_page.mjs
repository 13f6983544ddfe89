// The web page (examples/web) in a headless Chromium, whose WebGPU runs here on SwiftShader (the
// software Vulkan Chromium ships): the page starts, draws every method's frame on its
// canvases, and draws again when its budget slider and its scene change. Run by
// scripts/web.sh test (and `web.sh picture`, which keeps its screenshot).
//   node scripts/web_page.mjs URL [SCREENSHOT.png]
// With WEB_PAGE_SUMMARY=FILE, what it measured as JSON there (scripts/web_summary.py).
import { writeFileSync } from 'node:fs';
import { createRequire } from 'node:module';

const [url, screenshot] = process.argv.slice(2);
if (!url) {
  console.error('usage: web_page.mjs URL [SCREENSHOT.png]');
  process.exit(2);
}
const require = createRequire(process.env.PUPPETEER_FROM);
const puppeteer = require('puppeteer-core');
const browser = await puppeteer.launch({
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium-headless-shell',
  headless: 'shell',
  // WebGPU is behind a flag on Linux; no sandbox where the tests run as root.
  args: ['--no-sandbox', '--enable-unsafe-webgpu', '--enable-features=Vulkan', '--ignore-gpu-blocklist'],
  defaultViewport: { width: 1140, height: 520 },
});
const page = await browser.newPage();
const problems = [];
page.on('pageerror', (e) => problems.push(e.message));
page.on('console', (m) => m.type() === 'error' && problems.push(m.text()));

async function fail(why) {
  const status = await page.$eval('#status', (e) => e.textContent).catch(() => '?');
  console.error(`page: ${why} (status: ${status}; errors: ${problems.join(' | ') || 'none'})`);
  await browser.close();
  process.exit(1);
}
// Waits for the page's next "N methods in T ms" (the status is cleared first).
async function settled(what) {
  try {
    await page.waitForFunction(() => {
      const s = document.getElementById('status');
      if (s.className === 'error') return true;
      return / methods in \d+ ms/.test(s.textContent);
    }, { timeout: 180000, polling: 200 });
  } catch {
    await fail(`${what}: no frame after three minutes`);
  }
  if (await page.$eval('#status', (e) => e.className === 'error')) await fail(`${what}: the page shows an error`);
}
// Each figure: its caption, and its canvas's pixels (RGBA) read back through a 2D context.
const figures = () => page.$$eval('figure', (fs) => fs.map((f) => {
  const c = f.querySelector('canvas');
  const data = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
  let sum = 0;
  for (let i = 0; i < data.length; i++) sum = (sum * 31 + data[i]) >>> 0;
  let blank = true;
  for (let i = 0; i < data.length && blank; i++) blank = i % 4 === 3 || data[i] === 255;
  return { caption: f.querySelector('figcaption').innerText.replace(/\s+/g, ' '), sum, blank, size: [c.width, c.height] };
}));
const kib = (caption) => Number(/(\d+) KiB/.exec(caption)?.[1]);
async function restart() {
  await page.$eval('#status', (e) => { e.textContent = ''; });
}

await page.goto(url);
await settled('the first frame');
const first = await figures();
if (first.length !== 3) await fail(`${first.length} canvases, not 3`);
for (const f of first) {
  if (f.blank) await fail(`${f.caption}: a blank canvas`);
  if (!(kib(f.caption) > 0)) await fail(`a caption names no bytes: ${f.caption}`);
}
const firstStatus = await page.$eval('#status', (e) => e.textContent);
console.log(`page: ${firstStatus}`);
for (const f of first) console.log(`page:   ${f.caption}`);
if (screenshot) {
  await page.screenshot({ path: screenshot });
  console.log(`page: screenshot ${screenshot}`);
}

// The slider: DKB and VKB at a larger budget keep more fragments, in more bytes.
await restart();
await page.$eval('#budget', (e) => { e.value = '60'; e.dispatchEvent(new Event('input')); });
await settled('the slider at 60%');
const wider = await figures();
if (await page.$eval('#budget-label', (e) => e.textContent) !== '60%') await fail('the slider\'s label did not follow it');
for (const i of [0, 1]) {
  if (!(kib(wider[i].caption) > kib(first[i].caption))) {
    await fail(`${wider[i].caption} at 60% is no larger than ${first[i].caption} at 25%`);
  }
}
console.log(`page: at 60%: ${wider.slice(0, 2).map((f) => f.caption).join('; ')}`);

// Another scene.
await restart();
const scene = await page.$eval('#scene', (e) => {
  e.value = e.options[1].value;
  e.dispatchEvent(new Event('change'));
  return e.value;
});
await settled(`the scene ${scene}`);
const other = await figures();
if (other[2].sum === first[2].sum) await fail(`the scene ${scene} looks like the first one`);
const otherStatus = await page.$eval('#status', (e) => e.textContent);
console.log(`page: ${scene}: ${otherStatus}`);
if (process.env.WEB_PAGE_SUMMARY) {
  const ms = (status) => Number(/ methods in (\d+) ms/.exec(status)?.[1]);
  writeFileSync(process.env.WEB_PAGE_SUMMARY, JSON.stringify({
    size: first[0].size, first_ms: ms(firstStatus), scene, scene_ms: ms(otherStatus),
  }, null, 1));
}
if (problems.length) await fail('the page logged errors');
await browser.close();
console.log('page: the page draws in a headless Chromium on its WebGPU, and follows its slider and scene');
