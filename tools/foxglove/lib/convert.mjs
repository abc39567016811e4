// rack-gui's messages (tools/gui/backend.h: class, components, data, map, gdos) as
// Foxglove messages: one JSON channel per component stream with the schema made from
// its class description, and Foxglove's well-known schemas (@foxglove/schemas) where
// one fits:
//
//   /rack/<system>/<name>            every class: its data as JSON, schema "rack.<Class>"
//   /rack/<system>/<name>/scan       Ladar: foxglove.LaserScan (frame "<name>")
//   /rack/<system>/<name>/points     Scan2D: foxglove.PointCloud (frame "base_link"; its
//                                    points are filtered, not evenly spaced in angle)
//   /rack/<system>/<name>/pose       Position, MCL, Odometry: foxglove.PoseInFrame ("map")
//   /rack/<system>/<name>/estimate   Position, MCL: foxglove.Odometry, the pose with its
//                                    covariance (6x6 over x, y, z and the rotations
//                                    about x, y, z: RACK's x, y, phi entries in it,
//                                    the rest zero), frame "map", body "base_link"
//   /rack/<system>/<name>/particles  MCL: foxglove.PosesInFrame (the particles shown)
//   /rack/<system>/<name>/path       Path: foxglove.PosesInFrame (the planned path)
//   /rack/<system>/map               the occupancy map: foxglove.Grid (0 free, 1 occupied,
//                                    2 unknown), frame "map"
//   /rack/<system>/tf                Position: foxglove.FrameTransforms map -> base_link
//   /rack/<system>/<name>/image      Camera (rack-gui's "image" messages, polled once a
//                                    second: its 0.9 MB samples are not streamed):
//                                    foxglove.RawImage (rgb8, mono8) or
//                                    foxglove.CompressedImage (jpeg), frame "<name>"
//   /rack/gdos                       every host's GDOS log: foxglove.Log
//
// A message from rack-gui that does not have the expected shape is skipped and counted
// (Converter.rejected, with the last reason), never thrown: the bridge keeps running.
//
// rack-gui's messages come parsed by lib/exact_json.mjs: a sample's time_ns (and any
// other integer past 2^53) is a BigInt, so that the times recorded are the producer's
// to the nanosecond; the messages made here are written with its stringifyExact.
import schemas from '@foxglove/schemas/jsonschema.js';

import { isInt } from './exact_json.mjs';

export const kJsonEncoding = 'json';
export const kSchemaEncoding = 'jsonschema';

const kKindSchema = {
  i8: { type: 'integer' }, u8: { type: 'integer', minimum: 0 }, bool: { type: 'boolean' },
  i16: { type: 'integer' }, u16: { type: 'integer', minimum: 0 }, i32: { type: 'integer' },
  u32: { type: 'integer', minimum: 0 }, i64: { type: 'integer' }, u64: { type: 'integer', minimum: 0 },
  f32: { type: 'number' }, f64: { type: 'number' },
};

// A JSON schema for a type of a class description ({"name","size","fields":[{name,kind,count}]}).
export function typeSchema(title, type) {
  const properties = {};
  for (const f of type.fields) {
    if (f.kind === 'char') {
      properties[f.name] = { type: 'string', maxLength: f.count };
    } else if (f.count > 1) {
      properties[f.name] = { type: 'array', items: { ...kKindSchema[f.kind] }, maxItems: f.count };
    } else {
      properties[f.name] = { ...(kKindSchema[f.kind] ?? {}) };
    }
  }
  return { title, description: `${type.name} (${type.size} bytes)`, type: 'object', properties };
}

// The schema of a component's JSON channel: the sample's header and its data.
export function dataSchema(cls) {
  return {
    title: `rack.${cls.class}`,
    description: `${cls.impl}: ${cls.summary}`,
    type: 'object',
    properties: {
      component: { type: 'string', description: 'TiMS address' },
      time_ns: { type: 'integer', description: 'sample time (ns)' },
      sequence: { type: 'integer' },
      data: typeSchema(cls.data.name, cls.data),
    },
  };
}

// The topics a component's data gives (onData below), to decide which streams a
// recording with --topics needs.
export function topicsOf(system, name, className) {
  const base = `/rack/${system}/${name}`;
  const extra = { Ladar: ['scan'], 'Scan2D': ['points'], Position: ['pose', 'estimate'], MCL: ['pose', 'estimate', 'particles'],
                  Odometry: ['pose'], Path: ['path'], Camera: ['image'] }[className] ?? [];
  const out = [base, ...extra.map((e) => `${base}/${e}`)];
  if (className === 'Position') out.push(`/rack/${system}/tf`);
  return out;
}

export function stamp(ns) {
  const t = BigInt(ns);
  return { sec: Number(t / 1000000000n), nsec: Number(t % 1000000000n) };
}

function yawQuaternion(phi) {
  return { x: 0, y: 0, z: Math.sin(phi / 2), w: Math.cos(phi / 2) };
}

function pose(x, y, phi) {
  return { position: { x, y, z: 0 }, orientation: yawQuaternion(phi) };
}

const kIdentity = pose(0, 0, 0);

const kGdosLevel = { print: 2, detail: 1, info: 2, warning: 3, error: 4 };

const isNum = (v) => typeof v === 'number' && Number.isFinite(v);
const nums = (a) => Array.isArray(a) && a.every((v) => v === null || typeof v === 'number');

export class Converter {
  constructor() {
    this.classes = new Map();  // "<system>:<class id>" -> class message
    this.byClassName = new Map();  // "<system>:<class name>" -> class message
    this.components = new Map();  // address -> {address, name, class, system, state}
    this.rejected = 0;
    this.lastRejection = '';
  }

  reject(why) {
    this.rejected += 1;
    this.lastRejection = why;
    return [];
  }

  // One rack-gui message (a parsed JSON object) -> [{topic, schemaName, schema, time, message}],
  // time in ns as a BigInt.
  convert(m) {
    if (m === null || typeof m !== 'object' || typeof m.type !== 'string') return this.reject('not a rack-gui message');
    switch (m.type) {
      case 'class': return this.onClass(m);
      case 'components': return this.onComponents(m);
      case 'data': return this.onData(m);
      case 'map': return this.onMap(m);
      case 'gdos': return this.onGdos(m);
      case 'image': return this.onImage(m);
      default: return [];
    }
  }

  onClass(m) {
    if (!Number.isInteger(m.system) || !Number.isInteger(m.class_id) || typeof m.class !== 'string' ||
        !Array.isArray(m.commands) || !Array.isArray(m.parameters)) {
      return this.reject('class message without system, class_id, class, commands or parameters');
    }
    if (m.data !== null && (typeof m.data !== 'object' || !Array.isArray(m.data.fields))) {
      return this.reject(`class ${m.class}: data without fields`);
    }
    this.classes.set(`${m.system}:${m.class_id}`, m);
    this.byClassName.set(`${m.system}:${m.class}`, m);
    return [];
  }

  // Each "components" message lists every component rack-gui knows (all robots, every
  // round): it replaces the list. Merged into it instead, a component's first entry
  // stayed for good: rack-gui lists a component under its class number,
  // Class0x11(0/0), until its class description arrives and under its class name,
  // Ladar(0/0), after, so a client that connected before the description kept an
  // entry of an undescribed class ahead of the described one (the player then waited
  // for a class that never came: FoxgloveTest.ReplayIntoMclGivesTheRecordedLocalisation
  // in CI under load).
  onComponents(m) {
    if (!Array.isArray(m.robots)) return this.reject('components message without robots');
    const components = new Map();
    const list = (v) => (Array.isArray(v) ? v : []);  // (a malformed entry lists nothing, never throws)
    for (const r of m.robots) {
      for (const h of list(r?.hosts)) {
        for (const c of list(h?.components)) {
          if (typeof c?.address !== 'string') continue;
          components.set(c.address, { address: c.address, name: c.name, class: c.class, impl: c.impl,
                                      system: r.system, state: c.state });
        }
      }
    }
    this.components = components;
    return [];
  }

  classOf(system, className) {
    return this.byClassName.get(`${system}:${className}`);
  }

  onData(m) {
    if (typeof m.component !== 'string' || typeof m.name !== 'string' || typeof m.class !== 'string' ||
        !Number.isInteger(m.system) || !isInt(m.time_ns) || m.data === null || typeof m.data !== 'object') {
      return this.reject('data message without component, name, class, system, time_ns or data');
    }
    const cls = this.classOf(m.system, m.class);
    if (!cls || !cls.data) return [];  // its description has not arrived yet
    const base = `/rack/${m.system}/${m.name}`;
    const time = BigInt(m.time_ns);
    const out = [{
      topic: base, component: m.component, schemaName: `rack.${m.class}`, schema: dataSchema(cls), time,
      message: { component: m.component, time_ns: m.time_ns, sequence: m.sequence, data: m.data },
    }];
    const d = m.data;
    const ts = stamp(m.time_ns);
    switch (m.class) {
      case 'Ladar':
        if (isNum(d.start_angle) && isNum(d.angle_step) && nums(d.range)) {
          out.push({
            topic: `${base}/scan`, schemaName: 'foxglove.LaserScan', schema: schemas.LaserScan, time,
            message: {
              timestamp: ts, frame_id: m.name, pose: kIdentity, start_angle: d.start_angle,
              end_angle: d.start_angle + d.angle_step * Math.max(0, d.range.length - 1),
              ranges: d.range.map((r) => (r === null ? 0 : r)),
              intensities: nums(d.intensity) ? d.intensity.map((v) => v ?? 0) : [],
            },
          });
        } else {
          this.reject(`${m.component}: Ladar data without start_angle, angle_step or range`);
        }
        break;
      case 'Scan2D':
        if (nums(d.x) && nums(d.y) && d.x.length === d.y.length) {
          const bytes = Buffer.alloc(8 * d.x.length);
          d.x.forEach((x, i) => { bytes.writeFloatLE(x ?? 0, 8 * i); bytes.writeFloatLE(d.y[i] ?? 0, 8 * i + 4); });
          out.push({
            topic: `${base}/points`, schemaName: 'foxglove.PointCloud', schema: schemas.PointCloud, time,
            message: {
              timestamp: ts, frame_id: 'base_link', pose: kIdentity, point_stride: 8,
              fields: [{ name: 'x', offset: 0, type: 7 }, { name: 'y', offset: 4, type: 7 }],
              data: bytes.toString('base64'),
            },
          });
        } else {
          this.reject(`${m.component}: Scan2D data without x and y of one length`);
        }
        break;
      case 'Position':
      case 'MCL':
      case 'Odometry':
        if (isNum(d.x) && isNum(d.y) && isNum(d.phi)) {
          out.push({
            topic: `${base}/pose`, schemaName: 'foxglove.PoseInFrame', schema: schemas.PoseInFrame, time,
            message: { timestamp: ts, frame_id: 'map', pose: pose(d.x, d.y, d.phi) },
          });
          // The pose with its covariance (x, y, phi of RACK's 3x3 in the 6x6 of x, y, z,
          // roll, pitch, yaw); the Odometry class gives no covariance.
          const cov3 = m.class === 'MCL' && nums(d.covariance) && d.covariance.length === 9
            ? d.covariance.map((v) => v ?? 0)
            : m.class === 'Position' && isNum(d.var_x) && isNum(d.var_y) && isNum(d.var_phi)
              ? [d.var_x, 0, 0, 0, d.var_y, 0, 0, 0, d.var_phi] : null;
          if (cov3) {
            const at = [0, 1, 5];  // x, y, yaw in the 6x6
            const cov6 = new Array(36).fill(0);
            for (let i = 0; i < 3; ++i) for (let j = 0; j < 3; ++j) cov6[6 * at[i] + at[j]] = cov3[3 * i + j];
            out.push({
              topic: `${base}/estimate`, schemaName: 'foxglove.Odometry', schema: schemas.Odometry, time,
              message: { timestamp: ts, frame_id: 'map', body_frame_id: 'base_link', pose: pose(d.x, d.y, d.phi),
                         pose_covariance: cov6 },
            });
          }
          if (m.class === 'Position') {
            out.push({
              topic: `/rack/${m.system}/tf`, schemaName: 'foxglove.FrameTransforms', schema: schemas.FrameTransforms, time,
              message: { transforms: [{ timestamp: ts, parent_frame_id: 'map', child_frame_id: 'base_link',
                                        translation: { x: d.x, y: d.y, z: 0 }, rotation: yawQuaternion(d.phi) }] },
            });
          }
        } else {
          this.reject(`${m.component}: ${m.class} data without x, y and phi`);
        }
        if (m.class === 'MCL' && nums(d.particle_x) && nums(d.particle_y) && nums(d.particle_phi)) {
          out.push({
            topic: `${base}/particles`, schemaName: 'foxglove.PosesInFrame', schema: schemas.PosesInFrame, time,
            message: { timestamp: ts, frame_id: 'map',
                       poses: d.particle_x.map((x, i) => pose(x ?? 0, d.particle_y[i] ?? 0, d.particle_phi[i] ?? 0)) },
          });
        }
        break;
      case 'Path':
        if (nums(d.x) && nums(d.y) && d.x.length === d.y.length) {
          out.push({
            topic: `${base}/path`, schemaName: 'foxglove.PosesInFrame', schema: schemas.PosesInFrame, time,
            message: { timestamp: ts, frame_id: 'map',
                       poses: d.x.map((x, i) => {
                         const nx = i + 1 < d.x.length ? d.x[i + 1] - x : 0;
                         const ny = i + 1 < d.y.length ? d.y[i + 1] - d.y[i] : 0;
                         return pose(x ?? 0, d.y[i] ?? 0, Math.atan2(ny, nx));
                       }) },
          });
        }
        break;
      default:
        break;
    }
    for (const item of out) item.component = m.component;  // whose stream feeds it (not part of the message)
    return out;
  }

  onMap(m) {
    if (!Number.isInteger(m.system) || !Number.isInteger(m.width) || !Number.isInteger(m.height) ||
        !isNum(m.resolution) || typeof m.cells !== 'string') {
      return this.reject('map message without system, width, height, resolution or cells');
    }
    const cells = Buffer.from(m.cells, 'base64');
    if (cells.length !== m.width * m.height) {
      return this.reject(`map of robot ${m.system}: ${cells.length} cells, expected ${m.width}x${m.height}`);
    }
    return [{
      topic: `/rack/${m.system}/map`, schemaName: 'foxglove.Grid', schema: schemas.Grid, time: 0n, latched: true,
      message: {
        timestamp: stamp(0), frame_id: 'map',
        pose: pose(m.origin_x ?? 0, m.origin_y ?? 0, m.origin_yaw ?? 0),
        column_count: m.width, cell_size: { x: m.resolution, y: m.resolution },
        row_stride: m.width, cell_stride: 1,
        fields: [{ name: 'state', offset: 0, type: 1 }],
        data: m.cells,
      },
    }];
  }

  // A camera image: raw (rgb, mono) or JPEG, the pixels base64 as rack-gui sends them.
  onImage(m) {
    if (typeof m.component !== 'string' || !Number.isInteger(m.system) || !isInt(m.time_ns) ||
        !Number.isInteger(m.width) || !Number.isInteger(m.height) || typeof m.format !== 'string' ||
        typeof m.data !== 'string') {
      return this.reject('image message without component, system, time_ns, width, height, format or data');
    }
    const comp = this.components.get(m.component);
    if (!comp) return [];  // not listed yet: its name is not known
    const topic = `/rack/${m.system}/${comp.name}/image`;
    const time = BigInt(m.time_ns);
    const timestamp = stamp(m.time_ns);
    if (m.format === 'jpeg') {
      return [{ topic, component: m.component, schemaName: 'foxglove.CompressedImage', schema: schemas.CompressedImage, time,
                message: { timestamp, frame_id: comp.name, data: m.data, format: 'jpeg' } }];
    }
    const channels = { rgb: 3, mono: 1 }[m.format];
    if (!channels) return this.reject(`${m.component}: image format '${m.format}' (expected rgb, mono or jpeg)`);
    const bytes = Buffer.from(m.data, 'base64').length;
    if (bytes !== m.width * m.height * channels) {
      return this.reject(`${m.component}: image of ${bytes} bytes, expected ${m.width}x${m.height}x${channels}`);
    }
    return [{ topic, component: m.component, schemaName: 'foxglove.RawImage', schema: schemas.RawImage, time,
              message: { timestamp, frame_id: comp.name, width: m.width, height: m.height,
                         encoding: m.format === 'rgb' ? 'rgb8' : 'mono8', step: m.width * channels, data: m.data } }];
  }

  onGdos(m) {
    if (!Array.isArray(m.records)) return this.reject('gdos message without records');
    const out = [];
    for (const r of m.records) {
      if (r === null || typeof r !== 'object' || !isInt(r.time_ns) || typeof r.text !== 'string') {
        this.reject('GDOS record without time_ns or text');
        continue;
      }
      out.push({
        topic: '/rack/gdos', schemaName: 'foxglove.Log', schema: schemas.Log, time: BigInt(r.time_ns),
        message: {
          timestamp: stamp(r.time_ns), level: kGdosLevel[r.level] ?? 0, message: r.text,
          name: `${r.host ?? ''}/${r.name || r.source || ''}`, file: '', line: 0,
        },
      });
    }
    return out;
  }
}
