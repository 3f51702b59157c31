// An independent reading of a BCF 2.1 file for test_bcf.cpp: @parametricos/bcf-js (MPL-2.0)
// opens it and gives topics, cameras, component counts and snapshots; the clipping planes and
// the components' AuthoringToolIds, which bcf-js 0.2.6 does not return, are read from the same
// archive with the zip reader and XML parser bcf-js itself uses (unzipit, fast-xml-parser),
// every value kept as text.
// Usage: node read_bcf.js NODE_MODULES_DIR FILE.bcf
// Prints one line of JSON on stdout; exit 2 when the reader cannot run or cannot open the file.
const path = require("path");
const fs = require("fs");
const modules = process.argv[2];
const file = process.argv[3];
console.log = (...args) => console.error(...args);  // bcf-js logs its errors on stdout

async function main() {
  const { BcfReader } = require(path.join(modules, "@parametricos/bcf-js/dist/2.1"));
  const { XMLParser } = require(path.join(modules, "fast-xml-parser"));
  const xml = new XMLParser({ ignoreAttributes: false, attributeNamePrefix: "@_", parseTagValue: false,
                              parseAttributeValue: false, isArray: (name) =>
                                ["ClippingPlane", "Component", "Color"].includes(name) });
  const reader = new BcfReader();
  await reader.read(new Uint8Array(fs.readFileSync(file)));
  if (!reader.project || !reader.project.markups) {
    process.stdout.write(JSON.stringify({ error: "bcf-js could not read " + file }) + "\n");
    process.exit(2);
  }
  const toolIds = (list) => (list || []).map((c) => c.AuthoringToolId);
  const topics = [];
  for (const markup of reader.project.markups) {
    const topic = markup.topic;
    const viewpoints = [];
    for (const vp of markup.viewpoints || []) {
      const ref = (topic.viewpoints || []).find((r) => r.guid === vp.guid) || {};
      const raw = xml.parse(await reader.getEntry(topic.guid + "/" + ref.viewpoint).text()).VisualizationInfo;
      const c = vp.perspective_camera;
      const comps = vp.components || {};
      const rawComps = raw.Components || {};
      const snapshot = ref.snapshot ? reader.getEntry(topic.guid + "/" + ref.snapshot) : undefined;
      const png = snapshot ? new Uint8Array(await snapshot.arrayBuffer()) : new Uint8Array();
      viewpoints.push({
        guid: vp.guid,
        camera: c && {
          eye: [c.camera_view_point.x, c.camera_view_point.y, c.camera_view_point.z],
          direction: [c.camera_direction.x, c.camera_direction.y, c.camera_direction.z],
          up: [c.camera_up_vector.x, c.camera_up_vector.y, c.camera_up_vector.z],
          fov: c.field_of_view,
        },
        clipping_planes: ((raw.ClippingPlanes || {}).ClippingPlane || []).map((p) => ({
          location: [p.Location.X, p.Location.Y, p.Location.Z].map(Number),
          direction: [p.Direction.X, p.Direction.Y, p.Direction.Z].map(Number),
        })),
        selection_count: (comps.selection || []).length,
        selection: toolIds((rawComps.Selection || {}).Component),
        default_visibility: String(comps.visibility && comps.visibility.default_visibility),
        exceptions: toolIds(((rawComps.Visibility || {}).Exceptions || {}).Component),
        coloring: ((rawComps.Coloring || {}).Color || []).map((g) => ({ color: g["@_Color"], ids: toolIds(g.Component) })),
        snapshot_bytes: png.length,
        snapshot_is_png: png.length > 8 && png[0] === 0x89 && png[1] === 0x50 && png[2] === 0x4e && png[3] === 0x47,
      });
    }
    topics.push({ guid: topic.guid, title: topic.title, creation_date: topic.creation_date, viewpoints });
  }
  process.stdout.write(JSON.stringify({ version: String(reader.project.version), topics }) + "\n");
}
main().catch((e) => {
  process.stdout.write(JSON.stringify({ error: String(e) }) + "\n");
  process.exit(2);
});
