// Parameter forms generated from a plugin's JSON schema (GET /plugins): numbers, integers, enums, booleans,
// strings. The service validates again; this only offers the right inputs with their defaults.

/** Fill ``container`` with one input per schema property; returns read() -> params object. */
export function parametersForm(container, schema) {
  const properties = Object.entries(schema?.properties ?? {});
  const readers = properties.map(([name, property]) => {
    const field = document.createElement("label");
    field.title = property.description ?? "";
    field.append(`${property.title ?? name} `);
    const { input, read } = inputFor(property);
    input.name = name;
    field.append(input);
    container.append(field);
    return [name, read];
  });
  container.hidden = readers.length === 0;
  return () => {
    const params = {};
    for (const [name, read] of readers) {
      const value = read();
      if (value !== undefined) params[name] = value;
    }
    return params;
  };
}

function inputFor(property) {
  if (property.enum) {
    const select = document.createElement("select");
    for (const option of property.enum) select.append(new Option(String(option), String(option)));
    select.value = String(property.default ?? property.enum[0]);
    return { input: select, read: () => property.enum.find((option) => String(option) === select.value) };
  }
  const input = document.createElement("input");
  if (property.type === "boolean") {
    input.type = "checkbox";
    input.checked = Boolean(property.default);
    return { input, read: () => input.checked };
  }
  if (property.type === "number" || property.type === "integer") {
    input.type = "number";
    input.step = property.type === "integer" ? "1" : "any";
    for (const bound of ["minimum", "maximum"]) {
      if (property[bound] !== undefined) input[bound.slice(0, 3)] = String(property[bound]);
    }
    input.value = property.default ?? "";
    return { input, read: () => (input.value === "" ? undefined : Number(input.value)) };
  }
  input.type = "text";
  input.value = property.default ?? "";
  return { input, read: () => (input.value === "" ? undefined : input.value) };
}
