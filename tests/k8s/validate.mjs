// Validates Kubernetes objects against the Kubernetes OpenAPI schemas as packaged by
// kubernetes-models (types, required fields, enums, formats; unknown fields are not refused).
// Input on stdin: a JSON array of objects. Output: a JSON array, one {kind, name, error} each.
import { readFileSync } from "node:fs";

const objects = JSON.parse(readFileSync(0, "utf8"));
const results = [];
for (const object of objects) {
  const result = { kind: object.kind, name: object.metadata?.name ?? "", error: null };
  try {
    const group = object.apiVersion;  // "v1", "apps/v1", "policy/v1"
    const module = await import(`kubernetes-models/${group}`);
    const Model = module[object.kind];
    if (!Model) throw new Error(`no model of ${group} ${object.kind}`);
    new Model(object).validate();
  } catch (e) {
    result.error = String(e.message ?? e);
  }
  results.push(result);
}
process.stdout.write(JSON.stringify(results));
